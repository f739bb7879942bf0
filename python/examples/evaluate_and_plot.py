"""Evaluate two schemes on a floor, then plot their error CDF and one walk's trajectory.

    python python/examples/evaluate_and_plot.py [FLOOR_DIR] [--schemes wifi,ekf] [--out plot.png]

FLOOR_DIR defaults to the committed synthetic floor fixtures/sim/F1. Prints the pooled
figures (the "pooled" part of `wipdr eval --json`); with matplotlib installed, writes a PNG
with the error CDF of each scheme and the truth and tracks of the walk with the most
waypoints (located with the walks of the other protocol folds as training data, as
`wipdr locate` does).
"""

import argparse
import sys
from pathlib import Path

import numpy as np

import wipdr

REPO = Path(__file__).resolve().parents[2]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("floor", nargs="?", default=str(REPO / "fixtures" / "sim" / "F1"))
    ap.add_argument("--schemes", default="wifi,ekf")
    ap.add_argument("--out", default="wipdr-example.png")
    args = ap.parse_args(argv)
    schemes = args.schemes.split(",")

    floor = wipdr.read_floor(args.floor)
    result = wipdr.evaluate([floor], schemes)
    print(f"{floor.name}: {len(floor)} walks")
    print(f"{'scheme':<8} {'count':>6} {'mean':>7} {'p50':>7} {'p95':>7}")
    for s in schemes:
        r = result["pooled"][s]
        print(f"{s:<8} {r['count']:>6} {r['mean']:>7.2f} {r['p50']:>7.2f} {r['p95']:>7.2f}")

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot (pip install matplotlib)")
        return 0

    fig, (cdf, traj) = plt.subplots(1, 2, figsize=(12, 5))
    for s in schemes:
        errors = np.sort([e[1] for w in result["walks"] if w["scheme"] == s for e in w["errors"]])
        cdf.plot(errors, np.arange(1, len(errors) + 1) / len(errors), label=s)
    cdf.set_xlabel("error (m)")
    cdf.set_ylabel("share of waypoints")
    cdf.set_title(f"error CDF, {floor.name}")
    cdf.grid(True, alpha=0.3)
    cdf.legend()

    # The walk with the most waypoints, located with the walks of the other folds.
    folds = floor.folds()
    walks = floor.walks
    i = max(range(len(walks)), key=lambda k: len(walks[k].waypoints))
    walk = walks[i]
    training = wipdr.Floor([w for w, f in zip(walks, folds) if f != folds[i]], plan=floor.plan, name=floor.name)
    for wall in floor.plan.walls:
        traj.plot(wall[[0, 2]], wall[[1, 3]], color="0.8", linewidth=0.5)
    traj.plot(walk.waypoints[:, 1], walk.waypoints[:, 2], "k.-", label="truth")
    for s in schemes:
        track = wipdr.locate(walk, training, s)
        traj.plot(track[:, 1], track[:, 2], label=s, linewidth=1)
    traj.set_aspect("equal")
    traj.set_title(f"walk {walk.id}")
    traj.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
