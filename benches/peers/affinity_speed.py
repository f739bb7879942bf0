#!/usr/bin/env python3
"""Side-by-side speed of affinity propagation: scikit-learn versus `wipdr cluster`.

Both run on the same similarity matrices: the first N rows of a fingerprint CSV (default
TUT3 test.csv, N = 2,000 and 3,951), RSS with "not detected" (100) replaced by -110 dBm,
similarity = negative squared Euclidean distance, preference = median of all similarities
(scikit-learn's default), damping 0.9, max_iter 200, convergence_iter 15.

    python3 benches/peers/affinity_speed.py \
        --csv $WIPDR_DATA/fingerprint/TUT3/test.csv --rows 2000 3951 \
        --wipdr target/release/wipdr

Prints one line per (implementation, N): seconds, iterations, cluster count, and whether the
exemplar sets agree. The similarity-matrix construction is not timed for either side.
"""
import argparse
import json
import subprocess
import sys
import time
import warnings

import numpy as np
from sklearn.cluster import AffinityPropagation
from sklearn.exceptions import ConvergenceWarning

NOT_HEARD = -110.0


def load_rss(path, rows):
    with open(path) as f:
        header = f.readline().strip().split(",")
    ap_cols = [i for i, name in enumerate(header) if name.startswith("ap_")]
    data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=ap_cols, max_rows=rows)
    data[data == 100] = NOT_HEARD
    return data


def neg_sq_euclidean(x):
    sq = np.einsum("ij,ij->i", x, x)
    s = -(sq[:, None] + sq[None, :] - 2.0 * x @ x.T)
    np.fill_diagonal(s, 0.0)
    return np.minimum(s, 0.0)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--csv", required=True)
    p.add_argument("--rows", type=int, nargs="+", default=[2000, 3951])
    p.add_argument("--wipdr", default=None, help="path to the wipdr binary (optional)")
    p.add_argument("--damping", type=float, default=0.9)
    p.add_argument("--max-iter", type=int, default=200)
    p.add_argument("--convergence-iter", type=int, default=15)
    p.add_argument("--precision", nargs="+", default=["f32"], help="wipdr matrix precision(s)")
    a = p.parse_args()
    for n in a.rows:
        x = load_rss(a.csv, n)
        s = neg_sq_euclidean(x)
        ap = AffinityPropagation(
            affinity="precomputed",
            damping=a.damping,
            max_iter=a.max_iter,
            convergence_iter=a.convergence_iter,
            random_state=0,
        )
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always", ConvergenceWarning)
            t0 = time.perf_counter()
            ap.fit(s)
            dt = time.perf_counter() - t0
        converged = not any(issubclass(x.category, ConvergenceWarning) for x in w)
        sk = sorted(int(i) for i in ap.cluster_centers_indices_)
        print(
            f"sklearn N={n} seconds={dt:.3f} iterations={ap.n_iter_} "
            f"clusters={len(sk)} converged={converged}",
            flush=True,
        )
        for precision in a.precision if a.wipdr else []:
            cmd = [
                a.wipdr, "cluster", "--csv", a.csv, "--rows", str(n),
                "--similarity", "signal", "--preference", "median",
                "--damping", str(a.damping), "--max-iter", str(a.max_iter),
                "--convergence-iter", str(a.convergence_iter), "--json",
                "--precision", precision,
            ]
            out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            res = json.loads(out.strip().splitlines()[-1])
            rs = sorted(res["exemplars"])
            print(
                f"wipdr {precision} N={n} seconds={res['seconds']:.3f} iterations={res['iterations']} "
                f"clusters={len(rs)} converged={res['converged']} "
                f"speedup={dt / res['seconds']:.1f}x same_exemplars={rs == sk}",
                flush=True,
            )


if __name__ == "__main__":
    sys.exit(main())
