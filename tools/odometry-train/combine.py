"""Would the step model and the learned odometry do better together? A feasibility check on
the leave-one-floor-out segments: each segment's step displacement (isotropic covariance
(k x length)^2 + 0.05 m^2) and learned displacement (its learned covariance x g) combined by
inverse covariance, k and g picked on the other four floors (the held-out floor never
chooses them). Also prints the correlation of the two sources' error vectors, and the
learned covariance's calibration: the smallest scale that puts 95 % of the four training
floors' segments inside their 95 % ellipse, and the share of the held-out floor's segments
inside with it.

    odometry-train score --cache C          # writes C/lofo/vectors_<floor>.json
    python3 combine.py C/lofo
"""
import glob
import json
import math
import os
import sys


def combined_error(v, k, g):
    """|truth - combination| of one segment `v` = truth, steps, learned (m), learned cov (m²)."""
    tx, ty, sx, sy, lx, ly, c0, c1, c2 = v
    vs = (k * max(math.hypot(sx, sy), 0.5)) ** 2 + 0.05
    a, b, c = g * c0, g * c1, g * c2
    det = a * c - b * b
    ia, ib, ic = c / det, -b / det, a / det
    sa, sb, sc = ia + 1 / vs, ib, ic + 1 / vs
    sdet = sa * sc - sb * sb
    pa, pb, pc = sc / sdet, -sb / sdet, sa / sdet
    rx = ia * lx + ib * ly + sx / vs
    ry = ib * lx + ic * ly + sy / vs
    ex, ey = pa * rx + pb * ry, pb * rx + pc * ry
    return math.hypot(tx - ex, ty - ey)


CHI2_2_95 = 5.991464547107979


def inside_95(v, g):
    """Whether the segment's truth lies in the learned 95 % ellipse with the covariance x g."""
    rx, ry = v[0] - v[4], v[1] - v[5]
    a, b, c = g * v[6], g * v[7], g * v[8]
    det = a * c - b * b
    return det > 0 and (c * rx * rx - 2 * b * rx * ry + a * ry * ry) / det <= CHI2_2_95


def coverage(vs, g):
    return sum(inside_95(v, g) for v in vs) / len(vs)


def mean(xs):
    return sum(xs) / len(xs)


def main(folder):
    floors = {}
    for p in sorted(glob.glob(os.path.join(folder, "vectors_*.json"))):
        floors[os.path.basename(p)[len("vectors_"):-len(".json")]] = json.load(open(p))
    if not floors:
        raise SystemExit(f"no vectors_*.json in {folder}: run `odometry-train score` first")
    grid = [(k, g) for k in [0.05, 0.08, 0.1, 0.12, 0.15, 0.2, 0.25, 0.3, 0.4]
            for g in [0.5, 1, 2, 4, 16]]
    pooled = {"combined": [], "steps": [], "learned": []}
    for f, vs in floors.items():
        train = [v for other, vv in floors.items() if other != f for v in vv]
        k, g = min(grid, key=lambda kg: mean([combined_error(v, *kg) for v in train]))
        c = [combined_error(v, k, g) for v in vs]
        s = [math.hypot(v[0] - v[2], v[1] - v[3]) for v in vs]
        lr = [math.hypot(v[0] - v[4], v[1] - v[5]) for v in vs]
        print(f"{f}: k {k} g {g}: combined {mean(c):.3f} steps {mean(s):.3f} "
              f"learned {mean(lr):.3f} ({len(vs)} segments)")
        pooled["combined"] += c
        pooled["steps"] += s
        pooled["learned"] += lr
    print(f"pooled: combined {mean(pooled['combined']):.3f} steps {mean(pooled['steps']):.3f} "
          f"learned {mean(pooled['learned']):.3f} ({len(pooled['steps'])} segments)")
    allv = [v for vv in floors.values() for v in vv]
    es = [(v[0] - v[2], v[1] - v[3]) for v in allv]
    el = [(v[0] - v[4], v[1] - v[5]) for v in allv]
    num = sum(a[0] * b[0] + a[1] * b[1] for a, b in zip(es, el))
    den = math.sqrt(sum(a[0] ** 2 + a[1] ** 2 for a in es) * sum(b[0] ** 2 + b[1] ** 2 for b in el))
    print(f"correlation of the two sources' error vectors: {num / den:.3f}")
    held = 0.0
    for f, vs in floors.items():
        train = [v for other, vv in floors.items() if other != f for v in vv]
        scales = [x / 100 for x in range(10, 401)]
        g = next((x for x in scales if coverage(train, x) >= 0.95), scales[-1])
        c = coverage(vs, g)
        held += c * len(vs)
        print(f"{f}: covariance x {g:.2f} (95 % on the training floors): "
              f"{100 * coverage(vs, 1.0):.1f} % -> {100 * c:.1f} % inside the ellipse")
    n = sum(len(vs) for vs in floors.values())
    print(f"pooled: {100 * held / n:.1f} % inside with each floor's scale "
          f"({100 * coverage(allv, 1.0):.1f} % unscaled)")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "/work/odometry-cache/lofo")
