#!/usr/bin/env python3
"""Side-by-side accuracy and speed of brute-force k-NN: scikit-learn versus `wipdr`.

Both answer the same queries (DIR/test.csv) against the same radio map (DIR/train.csv), RSS
with "not detected" (100) replaced by -110 dBm, Euclidean distance:
1-NN and distance-weighted 5-NN (`KNeighborsRegressor(algorithm="brute", weights="distance")`
for x, y). scikit-learn's batch `predict` is timed (best of --repeat runs); then
`wipdr fingerprint-eval` runs on the same files in the same script and reports its own batch
queries per second (wall clock of the whole batch, matching only, like `predict`).

    pip install scikit-learn   # not part of CI
    cargo build --release -p wipdr
    python3 benches/peers/knn_speed.py --dataset $WIPDR_DATA/fingerprint/UJI1 \
        --wipdr target/release/wipdr

Single-query latency of wipdr is measured by the criterion bench
(`cargo bench -p wipdr-benches --bench matchers`); this script also reports scikit-learn's
single-query latency (one `predict` call on one row, median of 200).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from sklearn.neighbors import KNeighborsRegressor

NOT_HEARD = -110.0


def load(path):
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    with open(path) as f:
        header = f.readline().strip().split(",")
    n_aps = len(header) - 5
    rss = data[:, :n_aps]
    rss = np.where(rss == 100, NOT_HEARD, rss)
    return rss, data[:, n_aps : n_aps + 2], data[:, n_aps + 3]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--wipdr", default="target/release/wipdr")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    name = os.path.basename(os.path.normpath(args.dataset))
    xtr, ytr, _ = load(os.path.join(args.dataset, "train.csv"))
    xte, yte, _ = load(os.path.join(args.dataset, "test.csv"))
    results = {}
    for label, k, weights in [("nn", 1, "uniform"), ("wknn", 5, "distance")]:
        model = KNeighborsRegressor(n_neighbors=k, algorithm="brute", weights=weights)
        model.fit(xtr, ytr)
        best = float("inf")
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            pred = model.predict(xte)
            best = min(best, time.perf_counter() - t0)
        err = np.linalg.norm(pred - yte, axis=1).mean()
        lat = []
        for i in range(min(200, len(xte))):
            t0 = time.perf_counter()
            model.predict(xte[i : i + 1])
            lat.append(time.perf_counter() - t0)
        results[label] = (err, len(xte) / best, float(np.median(lat)) * 1e3)
        print(
            f"sklearn {name} {label}: mean 2D {err:.3f} m, batch {len(xte) / best:.0f} q/s, "
            f"single-query median {np.median(lat) * 1e3:.3f} ms"
        )
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "wipdr.json")
        cmd = [args.wipdr, "fingerprint-eval", "--dataset", args.dataset, "--matcher", "nn",
               "wknn", "--k", "5", "--json", out]
        best = {}
        for _ in range(args.repeat):
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            with open(out) as f:
                for r in json.load(f)["results"]:
                    prev = best.get(r["matcher"])
                    if prev is None or r["queries_per_second"] > prev["queries_per_second"]:
                        best[r["matcher"]] = r
    for label in ["nn", "wknn"]:
        r = best[label]
        ratio = r["queries_per_second"] / results[label][1]
        print(
            f"wipdr   {name} {label}: mean 2D {r['mean_2d']:.3f} m, batch "
            f"{r['queries_per_second']:.0f} q/s = {ratio:.1f}x scikit-learn"
        )


if __name__ == "__main__":
    sys.exit(main())
