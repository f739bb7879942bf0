#!/usr/bin/env python3
"""Are the Wi-Fi fixes' errors a property of the place or of the walk? From a
`wipdr eval --json F --json-tracks` file (its `walk_data`: each test walk's fixes and
waypoints), with the truth at each fix interpolated between waypoints:

1. a **bias field** learned from the other folds' walks of the floor: each fix is moved by
   the kernel-weighted mean error (truth - fix) of the training fixes near it (Gaussian
   kernel of width H metres over fix positions, shrunk by `s / (s + N0)` where `s` is the
   kernel sum); prints the fixes' mean / median error before and after, per floor. If the
   errors were the place's, this would shrink them.
2. the fixes' error quantiles, a fit of their distances to two Gaussians and a uniform
   part, and the share of their error variance (per axis, pooled) that is each walk's own mean
   error (a walk-level bias) rather than scatter about it.
3. per floor, the length of each walk's mean fix error, averaged over the floors' walks
   weighted by their scored waypoints (the schemes' `count` when the file holds per-walk
   results, so both columns weigh a walk alike; else all its waypoints): the error of a perfect PDR shape placed by the walk's own
   fixes (their least-squares translation), a floor for any placement from Wi-Fi alone
   that walls and the shape's turns would have to beat; beside it, each scheme's mean
   error over the same walks when the file holds the schemes' per-walk results.

(The other folds' fixes were made with radio maps that include the test walk's fold, which
can only flatter the bias field.) Needs numpy:

    wipdr eval --data $F --schemes wifi --json tracks.json --json-tracks
    python3 docs/results/fix_errors.py tracks.json [H=3] [N0=2]
"""
import json
import sys

import numpy as np


def truth_at(waypoints, t):
    """The position interpolated between the waypoints around `t`, or None outside them."""
    for a, b in zip(waypoints, waypoints[1:]):
        if a[0] <= t <= b[0]:
            u = (t - a[0]) / max(1, b[0] - a[0])
            return a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])
    return None


def rayleigh_mixture(r, reach=100.0, rounds=300):
    """EM fit of the error distances `r` to two isotropic 2-D Gaussians (Rayleigh in `r`)
    and a uniform part over a disc of radius `reach`: [(share, sd)], uniform share."""
    r = np.asarray(r, dtype=float)
    shares, sds, uniform = np.array([0.5, 0.4]), np.array([3.0, 9.0]), 0.1
    for _ in range(rounds):
        dens = shares[:, None] * r / sds[:, None] ** 2 * np.exp(-r ** 2 / (2 * sds[:, None] ** 2))
        flat = np.where(r <= reach, uniform * 2 * r / reach ** 2, 0.0)
        total = np.maximum(dens.sum(0) + flat, 1e-300)
        resp, resp_flat = dens / total, flat / total
        shares, uniform = resp.mean(1), resp_flat.mean()
        sds = np.sqrt((resp * r ** 2).sum(1) / (2 * np.maximum(resp.sum(1), 1e-12)))
    return list(zip(shares, sds)), uniform


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    h = float(sys.argv[2]) if len(sys.argv) > 2 else 3.0
    n0 = float(sys.argv[3]) if len(sys.argv) > 3 else 2.0
    with open(sys.argv[1]) as f:
        run = json.load(f)
    walks = run.get("walk_data")
    if not walks:
        sys.exit("no walk_data: run wipdr eval with --json-tracks")
    rows = {}
    for k, w in enumerate(walks):
        for t, x, y in w["fixes"]:
            truth = truth_at(w["waypoints"], t)
            if truth is not None:
                rows.setdefault(w["floor"], []).append((w["fold"], k, x, y, *truth))
    before_all, after_all, within, total, walk_count = [], [], 0.0, 0.0, 0
    print(f"bias field, H = {h} m, N0 = {n0}: floor, fixes, mean / median error before -> after")
    for floor, r in sorted(rows.items()):
        a = np.array(r, dtype=float)
        before, after = [], []
        for fold in np.unique(a[:, 0]):
            test, train = a[a[:, 0] == fold], a[a[:, 0] != fold]
            if len(train) == 0:
                continue
            d2 = ((test[:, None, 2:4] - train[None, :, 2:4]) ** 2).sum(-1)
            kernel = np.exp(-d2 / (2 * h * h))
            s = kernel.sum(1)
            bias = (kernel[:, :, None] * (train[None, :, 4:6] - train[None, :, 2:4])).sum(1)
            bias /= np.maximum(s, 1e-12)[:, None]
            moved = test[:, 2:4] + (s / (s + n0))[:, None] * bias
            before += list(np.hypot(*(test[:, 2:4] - test[:, 4:6]).T))
            after += list(np.hypot(*(moved - test[:, 4:6]).T))
        print(f"{floor:10s} {len(before):5d} {np.mean(before):6.2f} / {np.median(before):5.2f}"
              f" -> {np.mean(after):6.2f} / {np.median(after):5.2f}")
        before_all += before
        after_all += after
        err = a[:, 4:6] - a[:, 2:4]
        for walk in np.unique(a[:, 1]):
            walk_count += 1
            e = err[a[:, 1] == walk]
            within += ((e - e.mean(0)) ** 2).sum()
        total += ((err - err.mean(0)) ** 2).sum()
    print(f"pooled     {len(before_all):5d} {np.mean(before_all):6.2f} / {np.median(before_all):5.2f}"
          f" -> {np.mean(after_all):6.2f} / {np.median(after_all):5.2f}")
    q = np.percentile(before_all, [25, 50, 75, 90, 95, 99])
    print("fix error quantiles p25 / p50 / p75 / p90 / p95 / p99: "
          + " / ".join(f"{v:.1f}" for v in q) + " m")
    components, flat = rayleigh_mixture(before_all)
    (a1, s1), (a2, s2) = sorted(components, key=lambda c: c[1])
    print(f"fit: {100 * a1:.0f} % N({s1:.1f} m) + {100 * a2:.0f} % N({s2:.1f} m) per axis"
          f" + {100 * flat:.1f} % uniform within 100 m")
    if total > 0:
        print(f"walk-level share of the fixes' error variance: {100 * (1 - within / total):.0f} %"
              f" (independent errors would give about {100 * walk_count / len(before_all):.0f} %:"
              " each walk's mean absorbs one fix's share)")
    walk_bias_floor(walks, run.get("walks", []))


def walk_bias_floor(walks, results):
    """Per floor, the mean length of each walk's mean fix error, beside each scheme's mean
    error on those walks, both weighted by the walk's scored waypoints (the results' `count`;
    all its waypoints when no result names the walk)."""
    scored = {}
    for r in results:
        scored.setdefault(r["scheme"], {})[r["walk"]] = (r["count"], r["mean"])
    schemes = sorted(scored)
    counts = {k: c for s in schemes for k, (c, _) in scored[s].items()}
    floors = {}
    for w in walks:
        err = [np.subtract((x, y), truth) for t, x, y in w["fixes"]
               if (truth := truth_at(w["waypoints"], t)) is not None]
        if err:
            weight = counts.get(w["walk"], len(w["waypoints"]))
            floors.setdefault(w["floor"], []).append((w["walk"], weight,
                                                      float(np.hypot(*np.mean(err, 0)))))
    print("walk-mean fix error (a Wi-Fi-placed perfect shape), weighted by scored waypoints; "
          + ", ".join(f"{s} mean" for s in schemes))
    pooled = []
    for floor, rows in sorted(floors.items()) + [("pooled", None)]:
        rows = rows if rows is not None else pooled
        weight = sum(n for _, n, _ in rows)
        if weight == 0:
            continue
        line = f"{floor:10s} {len(rows):4d} walks {sum(n * b for _, n, b in rows) / weight:6.2f}"
        for s in schemes:
            hit = [(scored[s][k][0], scored[s][k][1]) for k, _, _ in rows if k in scored[s]]
            count = sum(c for c, _ in hit)
            if count:
                line += f"  {s} {sum(c * m for c, m in hit) / count:6.2f}"
        print(line)
        if floor != "pooled":
            pooled += rows


if __name__ == "__main__":
    main()
