#!/usr/bin/env python3
"""Where ILC walks start: how far each walk's first waypoint lies from the nearest first
waypoint of a training walk (the evaluation's folds: walks sorted by file name, walk i in
fold i mod 5, as `wipdr_eval::fold_rules::folds_by_name`). Tells whether a start prior at the
training walks' starts could help `pmf`'s first waypoints (docs/experiments.md, walk starts).

Standard library only; reads the data in place:

    python3 docs/results/walk_starts.py [DIR, default $WIPDR_DATA/ilc20] [site1/F1 site1/F2 ...]
"""
import glob
import gzip
import math
import os
import sys

# The data root: $WIPDR_DATA (relative to the repository), else ../shared/data beside it.
REPO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
DATA_ROOT = os.path.join(REPO, os.environ.get("WIPDR_DATA") or os.path.join("..", "shared", "data"))
DATA = sys.argv[1] if len(sys.argv) > 1 else os.path.join(DATA_ROOT, "ilc20")
FLOORS = sys.argv[2:] or ["site1/F1", "site1/F2", "site2/F1", "site2/F2", "site2/F3"]
FOLDS = 5


def first_waypoint(path):
    """The earliest TYPE_WAYPOINT (x, y) of a trace, or None without one."""
    best = None
    with gzip.open(path, "rt", errors="replace") if path.endswith(".gz") else open(path) as f:
        for line in f:
            p = line.rstrip("\n").split("\t")
            if len(p) >= 4 and p[1] == "TYPE_WAYPOINT":
                try:
                    t, x, y = int(p[0]), float(p[2]), float(p[3])
                except ValueError:
                    continue
                if best is None or t < best[0]:
                    best = (t, x, y)
    return None if best is None else best[1:]


def main():
    for floor in FLOORS:
        paths = sorted(glob.glob(os.path.join(DATA, floor, "path_data_files", "*.txt*")))
        starts = [(i % FOLDS, s) for i, s in enumerate(map(first_waypoint, paths))]
        starts = [(k, s) for k, s in starts if s is not None]
        d = sorted(
            min((math.dist(s, o) for j, o in starts if j != k), default=math.inf)
            for k, s in starts
        )
        n = len(d)
        if n == 0:
            print(f"{floor}: no walks with waypoints")
            continue
        within = 100.0 * sum(x < 3.0 for x in d) / n
        print(f"{floor}: {n} walks; nearest training start median {d[n // 2]:.1f} m, "
              f"p75 {d[int(0.75 * n)]:.1f}, p90 {d[int(0.9 * n)]:.1f}; within 3 m {within:.0f} %")


if __name__ == "__main__":
    main()
