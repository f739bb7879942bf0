#!/usr/bin/env python3
"""Where a scheme's 95 % radius fails: from a `wipdr eval --json` file, the share of scored
waypoints whose error is within the reported 95 % radius (2.45 x `sd_m`), per floor (an
IPIN logfile folder: per route `TrialNN`) and by the waypoint's distance to the fold's
nearest measured reference point (`coverage_m`). Tells whether an over-confident radius sits
in coverage gaps (docs/experiments.md, the radius by coverage).

Standard library only:

    wipdr eval --data $WIPDR_DATA/ipin2023 --schemes pmf --json ipin.json
    python3 docs/results/radius_by_coverage.py ipin.json [pmf]
"""
import collections
import json
import re
import statistics
import sys

EDGES = [3.0, 6.0, 12.0]  # metres from coverage: bins <3, 3-6, 6-12, >=12
K95 = 2.4477  # sqrt(chi2_2(0.95)): the 95 % radius of a circular Gaussian in sd units


def bin_of(c):
    for i, e in enumerate(EDGES):
        if c < e:
            return i
    return len(EDGES)


def label(i):
    lo = 0.0 if i == 0 else EDGES[i - 1]
    return f"<{EDGES[0]:g} m" if i == 0 else (f">={lo:g} m" if i == len(EDGES) else f"{lo:g}-{EDGES[i]:g} m")


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    scheme = sys.argv[2] if len(sys.argv) > 2 else "pmf"
    data = json.load(open(sys.argv[1]))
    by_group = collections.defaultdict(lambda: [0, 0])
    by_bin = collections.defaultdict(lambda: [0, 0])
    radii = []
    for w in data["walks"]:
        if w["scheme"] != scheme or not w.get("sd_m"):
            continue
        m = re.search(r"Trial\d+", w["walk"])
        group = m.group(0) if m else w["floor"]
        for err, sd, cov in zip(w["errors"], w["sd_m"], w["coverage_m"]):
            radii.append(K95 * sd)
            inside = err[1] <= K95 * sd
            for tally in (by_group[group], by_bin[bin_of(cov)]):
                tally[0] += inside
                tally[1] += 1
    if not by_group:
        sys.exit(f"no per-point sd_m for scheme {scheme} in {sys.argv[1]}")
    print(f"{scheme}: share of scored waypoints inside the 95 % radius")
    for g, (k, n) in sorted(by_group.items()):
        print(f"  {g:<28} {100 * k / n:5.1f} %  ({n} points)")
    print("by distance to coverage:")
    for i in sorted(by_bin):
        k, n = by_bin[i]
        print(f"  {label(i):<28} {100 * k / n:5.1f} %  ({n} points)")
    k = sum(v[0] for v in by_bin.values())
    n = sum(v[1] for v in by_bin.values())
    print(f"  {'all':<28} {100 * k / n:5.1f} %  ({n} points)")
    print(f"median 95 % radius: {statistics.median(radii):.1f} m")


if __name__ == "__main__":
    main()
