#!/usr/bin/env python3
"""A scheme's error by route, from a `wipdr eval --json` file: per route (the IPIN logfiles'
`TrialNN`, all repetitions together; an ILC walk is its own route), the scored points, the
mean error, the route's share of the summed error, the median distance to coverage and the
share of points 6 m or more from it (`coverage_m`), and each walk's first-point error.
Tells whether a building's error sits in a few routes and whether those are coverage gaps
(docs/results/ipin.md; docs/experiments.md, IPIN by route).

Standard library only:

    wipdr eval --data $WIPDR_DATA/ipin2023 --schemes pmf --json ipin.json
    python3 docs/results/errors_by_route.py ipin.json [pmf]
"""
import json
import re
import signal
import statistics
import sys


def route_of(walk):
    """`TrialNN` of an IPIN logfile's name, else the walk's own name."""
    m = re.search(r"Trial(\d+)", walk)
    return "Trial" + m.group(1) if m else walk


def main():
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # `| head` ends quietly
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    scheme = sys.argv[2] if len(sys.argv) > 2 else "pmf"
    with open(sys.argv[1]) as f:
        result = json.load(f)
    routes = {}
    for walk in result["walks"]:
        if walk["scheme"] == scheme and walk["errors"]:
            routes.setdefault(route_of(walk["walk"]), []).append(walk)
    if not routes:
        sys.exit(f"no scored walk of scheme {scheme!r} in {sys.argv[1]}")
    total = sum(e[1] for ws in routes.values() for w in ws for e in w["errors"])
    print(f"{scheme}: route, walks, points, mean m, share of summed error, "
          "coverage median m, points >= 6 m from coverage, first-point errors m")
    for route, walks in sorted(routes.items()):
        errors = [e[1] for w in walks for e in w["errors"]]
        coverage = [c for w in walks for c in w.get("coverage_m", [])]
        share = 100 * sum(errors) / total if total > 0 else 0.0
        cov = (f"{statistics.median(coverage):5.1f} {100 * sum(c >= 6 for c in coverage) / len(coverage):4.0f} %"
               if coverage else "    -      -")
        first = " ".join(f"{w['errors'][0][1]:.1f}" for w in walks)
        print(f"{route:12s} {len(walks):2d} {len(errors):4d} {statistics.mean(errors):6.2f} "
              f"{share:4.0f} % {cov}  {first}")


if __name__ == "__main__":
    main()
