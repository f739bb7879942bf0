"""The scripts in python/examples run."""

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import FIXTURE_FLOOR, REPO

EXAMPLES = REPO / "python" / "examples"


def test_the_example_evaluates_and_plots(tmp_path):
    pytest.importorskip("matplotlib", reason="matplotlib is not installed (optional)")
    out = tmp_path / "plot.png"
    r = subprocess.run(
        [sys.executable, str(EXAMPLES / "evaluate_and_plot.py"), str(FIXTURE_FLOOR), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "sim/F1: 10 walks" in r.stdout and "ekf" in r.stdout
    assert out.stat().st_size > 10_000
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_push_cost_script_runs():
    r = subprocess.run(
        [sys.executable, str(EXAMPLES / "push_cost.py"), str(FIXTURE_FLOOR), "--repeat", "1", "--schemes", "ekf"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "us/sample" in r.stdout and "Positioner.push_* ekf" in r.stdout
