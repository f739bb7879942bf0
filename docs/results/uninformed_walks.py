#!/usr/bin/env python3
"""Walks the Wi-Fi does not inform: from a `wipdr eval --json` file holding `wifi` and a fused
scheme, the walks whose every scored Wi-Fi error is at least MIN metres (default 15): the
whole walk lies outside the fold's radio-map coverage and every fix lands in some covered
place far from the walker, so no filter over the fixes can place the walk (only a floor plan
can, where it tells the places apart). Prints those walks with the scheme's and the fixes'
mean error, then the scheme's pooled mean with and without them
(docs/results/accuracy.md, "The walks the Wi-Fi does not inform").

Standard library only:

    wipdr eval --data $F --schemes wifi,pmf --offline --json off.json
    python3 docs/results/uninformed_walks.py off.json [pmf] [MIN]
"""
import json
import sys


def uninformed(data, scheme="pmf", min_m=15.0):
    """The walks of a `wipdr eval --json` document whose every scored Wi-Fi error is at
    least `min_m` metres, worst first: `(walks, total, points)`, each walk
    `(floor, walk id, points, wifi mean, scheme's summed error)`, with the scheme's summed
    error and scored points over every walk. Also used by `recipes/evaluation.py`."""
    key = lambda w: (w["floor"], w["walk"])
    wifi = {key(w): w for w in data["walks"] if w["scheme"] == "wifi"}
    fused = [w for w in data["walks"] if w["scheme"] == scheme and w["errors"]]
    total = sum(e[1] for w in fused for e in w["errors"])
    points = sum(len(w["errors"]) for w in fused)
    walks = []
    for w in sorted(fused, key=lambda w: -sum(e[1] for e in w["errors"])):
        f = wifi.get(key(w))
        if f is None or not f["errors"] or min(e[1] for e in f["errors"]) < min_m:
            continue
        wifi_mean = sum(e[1] for e in f["errors"]) / len(f["errors"])
        walks.append((w["floor"], w["walk"], len(w["errors"]), wifi_mean,
                      sum(e[1] for e in w["errors"])))
    return walks, total, points


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    scheme = sys.argv[2] if len(sys.argv) > 2 else "pmf"
    min_m = float(sys.argv[3]) if len(sys.argv) > 3 else 15.0
    data = json.load(open(sys.argv[1]))
    schemes = {w["scheme"] for w in data["walks"]}
    if "wifi" not in schemes or scheme not in schemes:
        sys.exit(f"need the schemes wifi and {scheme} in {sys.argv[1]}")
    walks, total, points = uninformed(data, scheme, min_m)
    if points == 0:
        sys.exit(f"no scored point of {scheme} in {sys.argv[1]}")
    print(f"walks whose every scored Wi-Fi error is >= {min_m:g} m:")
    print(f"  {'floor':<28} {'walk':<26} {'points':>6} {'wifi':>6} {scheme:>6}")
    for floor, walk, n, wifi_mean, s in walks:
        print(f"  {floor[-28:]:<28} {walk[:26]:<26} {n:>6} {wifi_mean:>6.1f} {s / n:>6.1f}")
    out_sum, out_points = sum(w[4] for w in walks), sum(w[2] for w in walks)
    print(f"{scheme} pooled mean: {total / points:.2f} m over {points} points")
    if out_points < points:
        rest = (total - out_sum) / (points - out_points)
        print(
            f"without those {out_points} points: {rest:.2f} m over {points - out_points};"
            f" they hold {100 * out_sum / total:.1f} % of the summed error"
        )


if __name__ == "__main__":
    main()
