#!/usr/bin/env python3
"""Where in a walk the error is: each scheme's scored errors pooled by the waypoint's rank
in its walk (0 = the first scored waypoint) and by the time since that first one (15 s bins),
with the share of the scheme's summed error each bin holds. From a `wipdr eval --json F` file:

    wipdr eval --data $F --schemes wifi,pdr,pmf --json run.json
    python3 docs/results/errors_by_time.py run.json [SCHEME ...]
"""
import json
import sys


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        walks = json.load(f)["walks"]
    wanted = set(sys.argv[2:])
    by_scheme = {}
    for w in walks:
        if wanted and w["scheme"] not in wanted:
            continue
        errors = w["errors"]
        if not errors:
            continue
        t0 = errors[0][0]
        bins = by_scheme.setdefault(w["scheme"], ({}, {}))
        for rank, (t, err, _floor_error) in enumerate(errors):
            bins[0].setdefault(min(rank, 6), []).append(err)
            bins[1].setdefault(min(int((t - t0) // 15000), 6), []).append(err)
    for scheme, (by_rank, by_time) in sorted(by_scheme.items()):
        total = sum(sum(v) for v in by_rank.values())
        print(f"{scheme}: by rank in the walk (count / mean / share of the summed error)")
        for k in sorted(by_rank):
            v = by_rank[k]
            label = f"{k}" if k < 6 else "6+"
            print(f"  {label:>4} {len(v):5d} {sum(v) / len(v):7.2f} {100 * sum(v) / total:5.1f} %")
        print(f"{scheme}: by time since the first scored waypoint")
        for k in sorted(by_time):
            v = by_time[k]
            label = f"{15 * k}-{15 * k + 15} s" if k < 6 else "90 s +"
            print(f"  {label:>9} {len(v):5d} {sum(v) / len(v):7.2f} {100 * sum(v) / total:5.1f} %")


if __name__ == "__main__":
    main()
