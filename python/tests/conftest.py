"""Shared paths and helpers of the wipdr Python tests.

- ``REPO``: the repository checkout (``python/tests/../..``).
- ``FIXTURE_FLOOR``: the committed synthetic floor ``fixtures/sim/F1``.
- ``DATA``: the real data root, as ``wipdr_io::data_root()`` finds it: ``$WIPDR_DATA`` when
  set and not empty (a relative path taken relative to the checkout), else
  ``../shared/data`` beside the checkout (as in CI); tests that need it skip with the reason
  when it is absent.
- ``wipdr_bin``: the CLI (``$WIPDR_BIN``, else ``target/debug/wipdr`` or
  ``target/release/wipdr`` of the checkout); with ``CI`` set a missing CLI fails instead of
  skipping.
"""

import json
import math
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
FIXTURE_FLOOR = REPO / "fixtures" / "sim" / "F1"
_DATA_ENV = os.environ.get("WIPDR_DATA")
DATA = REPO / _DATA_ENV if _DATA_ENV else REPO.parent / "shared" / "data"


@pytest.fixture(scope="session", autouse=True)
def parse_cache(tmp_path_factory):
    """One parse cache for the session, shared by the CLI and the package (both read
    ``$WIPDR_CACHE_DIR``): a floor is parsed from source once."""
    d = tmp_path_factory.mktemp("wipdr-cache")
    old = os.environ.get("WIPDR_CACHE_DIR")
    os.environ["WIPDR_CACHE_DIR"] = str(d)
    yield d
    if old is None:
        del os.environ["WIPDR_CACHE_DIR"]
    else:
        os.environ["WIPDR_CACHE_DIR"] = old


def cli_path():
    """The wipdr CLI binary, or None."""
    env = os.environ.get("WIPDR_BIN")
    if env:
        return Path(env)
    for profile in ("debug", "release"):
        p = REPO / "target" / profile / "wipdr"
        if p.is_file():
            return p
    return None


@pytest.fixture(scope="session")
def wipdr_bin():
    p = cli_path()
    if p is None or not p.is_file():
        if os.environ.get("CI"):
            pytest.fail("the wipdr CLI is not built (cargo build --bin wipdr) and CI is set")
        pytest.skip("the wipdr CLI is not built (cargo build --bin wipdr); set WIPDR_BIN")
    return p


def run_cli(wipdr_bin, *args, cwd=None):
    """Runs the CLI; fails the test with its output when it fails."""
    r = subprocess.run(
        [str(wipdr_bin), *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
    )
    assert r.returncode == 0, f"wipdr {' '.join(map(str, args))} failed:\n{r.stdout}\n{r.stderr}"
    return r


def cli_eval_json(wipdr_bin, tmp_path, dirs, schemes, config=None):
    """`wipdr eval --json` of `dirs` as a dict."""
    out = tmp_path / "eval.json"
    args = ["eval", "--data", *dirs, "--schemes", ",".join(schemes), "--json", out]
    if config is not None:
        args += ["--config", config]
    run_cli(wipdr_bin, *args)
    return json.loads(out.read_text())


def assert_close(a, b, path="", tol=1e-9):
    """Deep equality of JSON-like values, floats to `tol` (absolute and relative)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"{path}: keys {sorted(a)} vs {sorted(b) if isinstance(b, dict) else b}"
        for k in a:
            assert_close(a[k], b[k], f"{path}.{k}", tol)
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"{path}: lengths differ"
        for i, (x, y) in enumerate(zip(a, b)):
            assert_close(x, y, f"{path}[{i}]", tol)
    elif isinstance(a, float) or isinstance(b, float):
        assert a is not None and b is not None, f"{path}: {a} vs {b}"
        assert math.isclose(a, b, rel_tol=tol, abs_tol=tol), f"{path}: {a} vs {b}"
    else:
        assert a == b, f"{path}: {a!r} vs {b!r}"


from streams import push_all, push_items, stream_order  # noqa: E402,F401 (re-exported)
