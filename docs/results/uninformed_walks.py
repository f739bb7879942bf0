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


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    scheme = sys.argv[2] if len(sys.argv) > 2 else "pmf"
    min_m = float(sys.argv[3]) if len(sys.argv) > 3 else 15.0
    data = json.load(open(sys.argv[1]))
    key = lambda w: (w["floor"], w["walk"])
    wifi = {key(w): w for w in data["walks"] if w["scheme"] == "wifi"}
    fused = [w for w in data["walks"] if w["scheme"] == scheme and w["errors"]]
    if not wifi or not fused:
        sys.exit(f"need the schemes wifi and {scheme} in {sys.argv[1]}")
    total = sum(e[1] for w in fused for e in w["errors"])
    points = sum(len(w["errors"]) for w in fused)
    out_sum, out_points = 0.0, 0
    print(f"walks whose every scored Wi-Fi error is >= {min_m:g} m:")
    print(f"  {'floor':<28} {'walk':<26} {'points':>6} {'wifi':>6} {scheme:>6}")
    for w in sorted(fused, key=lambda w: -sum(e[1] for e in w["errors"])):
        f = wifi.get(key(w))
        if f is None or not f["errors"] or min(e[1] for e in f["errors"]) < min_m:
            continue
        s = sum(e[1] for e in w["errors"])
        out_sum += s
        out_points += len(w["errors"])
        wifi_mean = sum(e[1] for e in f["errors"]) / len(f["errors"])
        print(
            f"  {w['floor'][-28:]:<28} {w['walk'][:26]:<26} {len(w['errors']):>6}"
            f" {wifi_mean:>6.1f} {s / len(w['errors']):>6.1f}"
        )
    print(f"{scheme} pooled mean: {total / points:.2f} m over {points} points")
    if out_points < points:
        rest = (total - out_sum) / (points - out_points)
        print(
            f"without those {out_points} points: {rest:.2f} m over {points - out_points};"
            f" they hold {100 * out_sum / total:.1f} % of the summed error"
        )


if __name__ == "__main__":
    main()
