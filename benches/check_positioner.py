#!/usr/bin/env python3
"""Fails when the Positioner's per-sample cost grew past the figure in the docs.

Reads criterion's results of `cargo bench -p wipdr-benches --bench positioner` (the
`positioner_sample/<scheme>` groups: median time per walk divided by the walk's samples) and
the per-sample figures of docs/results/positioner.md (its table's rows
"| `ekf` | ... | 0.31 µs | ..."), and exits 1 when a scheme's cost exceeds its documented
figure by more than the allowed share (25 % by default).

    cargo bench -p wipdr-benches --bench positioner
    python3 benches/check_positioner.py            # or: just bench-check

A speed check for developers to run on a quiet machine, not a timed test in CI: the figures
move with the machine and its load.
"""

import argparse
import json
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
ROW = re.compile(r"^\|\s*`(?P<scheme>[a-z0-9_-]+)`\s*\|[^|]*\|\s*(?P<us>[0-9.]+)\s*µs")


def documented(doc: pathlib.Path) -> dict:
    """Per-sample figures (µs) of the doc's first table, by scheme."""
    figures = {}
    for line in doc.read_text(encoding="utf-8").splitlines():
        m = ROW.match(line)
        if m and m["scheme"] not in figures:
            figures[m["scheme"]] = float(m["us"])
    return figures


def measured(criterion: pathlib.Path, scheme: str) -> float:
    """Median µs per sample of criterion's newest `positioner_sample/<scheme>` run."""
    bench = criterion / "positioner_sample" / scheme / "new"
    estimates = json.loads((bench / "estimates.json").read_text())
    meta = json.loads((bench / "benchmark.json").read_text())
    elements = meta["throughput"]["Elements"]
    if elements <= 0:
        raise ValueError(f"{bench}: no samples in the throughput")
    return estimates["median"]["point_estimate"] / elements / 1000.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--doc", type=pathlib.Path, default=ROOT / "docs/results/positioner.md")
    parser.add_argument("--criterion", type=pathlib.Path, default=ROOT / "target/criterion")
    parser.add_argument("--allowed-growth", type=float, default=0.25,
                        help="largest accepted growth over the documented figure (0.25 = 25 %%)")
    args = parser.parse_args()
    figures = documented(args.doc)
    if not figures:
        print(f"{args.doc}: no per-sample figures found", file=sys.stderr)
        return 2
    failed = False
    for scheme, doc_us in sorted(figures.items()):
        try:
            now_us = measured(args.criterion, scheme)
        except (OSError, KeyError, ValueError) as e:
            print(f"{scheme}: no criterion result ({e}); run "
                  "`cargo bench -p wipdr-benches --bench positioner` first", file=sys.stderr)
            return 2
        growth = now_us / doc_us - 1.0
        verdict = "ok" if growth <= args.allowed_growth else "SLOWER"
        failed |= verdict != "ok"
        print(f"{scheme:>4}: {now_us:.3f} µs a sample, documented {doc_us:.3f} µs "
              f"({growth:+.0%}, allowed +{args.allowed_growth:.0%}): {verdict}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
