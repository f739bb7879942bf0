"""Helpers of the component recipes (comp_*.py); registers no table."""

import hashlib

from regenerate import WORK


def config_file(text):
    """A config file holding `text` under target/results/configs/, named by its content (so a
    run's cache key changes exactly when the config does); returns its path."""
    d = WORK / "configs"
    d.mkdir(parents=True, exist_ok=True)
    path = d / f"{hashlib.sha256(text.encode()).hexdigest()[:16]}.toml"
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return str(path)


def pct(x, sign=False):
    """A percentage, one decimal: `+4.3 %`, `93.0 %`."""
    return f"{x:+.1f} %" if sign else f"{x:.1f} %"


def mp(stats, keys=("mean", "p95")):
    """`7.14 / 21.04` from an eval summary."""
    return " / ".join(f"{stats[k]:.2f}" for k in keys)


def row(*cells):
    """A markdown table row; an empty cell is written `| |`."""
    return "|" + "|".join(f" {c} " if str(c) else " " for c in cells) + "|"
