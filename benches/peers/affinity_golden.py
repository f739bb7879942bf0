#!/usr/bin/env python3
"""Golden files for wipdr's affinity propagation, from scikit-learn.

Writes one JSON file per case into crates/fingerprint/tests/golden/affinity/. Each case holds
the similarity matrix (either integer points whose similarity is the negative squared
Euclidean distance, exact in f64, or the matrix itself as IEEE-754 bit patterns), the
settings, and scikit-learn's answer: exemplars (cluster_centers_indices_), labels, n_iter_
and whether it converged (no ConvergenceWarning). The row-median preference of paper 001 is
passed to scikit-learn as a per-point array (median of the row without its diagonal).

    pip install scikit-learn==1.9.1 numpy
    python3 benches/peers/affinity_golden.py crates/fingerprint/tests/golden/affinity

Run with scikit-learn 1.9.1 / NumPy 2.4 (the versions the committed files came from).
"""
import json
import os
import struct
import sys
import warnings

import numpy as np
import sklearn
from sklearn.cluster import AffinityPropagation
from sklearn.exceptions import ConvergenceWarning


def neg_sq(points):
    p = np.asarray(points, dtype=np.float64)
    d = p[:, None, :] - p[None, :, :]
    return -np.einsum("ijk,ijk->ij", d, d)


def row_median(s):
    n = s.shape[0]
    mask = ~np.eye(n, dtype=bool)
    return np.array([np.median(s[k][mask[k]]) for k in range(n)])


def bits(m):
    return [format(struct.unpack("<Q", struct.pack("<d", float(v)))[0], "016x") for v in m.ravel()]


def run(s, preference, damping, max_iter, conv, seed):
    pref = None
    if preference["kind"] == "value":
        pref = preference["value"]
    elif preference["kind"] == "row_median":
        pref = row_median(s)
    ap = AffinityPropagation(
        affinity="precomputed",
        damping=damping,
        max_iter=max_iter,
        convergence_iter=conv,
        preference=pref,
        random_state=seed,
    )
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        ap.fit(s.copy())
    converged = not any(issubclass(x.category, ConvergenceWarning) for x in w)
    return {
        "exemplars": [int(i) for i in ap.cluster_centers_indices_],
        "labels": [int(l) for l in ap.labels_],
        "n_iter": int(ap.n_iter_),
        "converged": converged,
    }


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "crates/fingerprint/tests/golden/affinity"
    os.makedirs(out_dir, exist_ok=True)
    rng = np.random.RandomState(20261122)
    cases = []

    # 1. three 2D blobs of integer points, global median, damping 0.5
    centres = np.array([[0, 0], [40, 5], [10, 50]])
    pts = np.vstack([c + rng.randint(-8, 9, size=(7, 2)) for c in centres])[:20]
    cases.append(("blobs2d_n20_global_median", {"points": pts.tolist()},
                  {"kind": "global_median"}, 0.5, 200, 15, 0))

    # 2. 5D blobs, row median (paper 001), damping 0.9
    centres = rng.randint(-60, 60, size=(6, 5))
    pts = np.vstack([c + rng.randint(-10, 11, size=(17, 5)) for c in centres])[:100]
    cases.append(("blobs5d_n100_row_median", {"points": pts.tolist()},
                  {"kind": "row_median"}, 0.9, 200, 15, 0))

    # 3. RSS-like integer fingerprints (many ties: the tie-breaking noise matters), N = 200
    rss = rng.randint(-100, -30, size=(200, 30))
    rss[rng.rand(200, 30) < 0.4] = -110
    cases.append(("rss_n200_global_median", {"points": rss.tolist()},
                  {"kind": "global_median"}, 0.9, 200, 15, 0))

    # 4. same, another seed and a fixed preference value
    cases.append(("rss_n200_value_pref_seed7", {"points": rss[:150].tolist()},
                  {"kind": "value", "value": -60000.0}, 0.7, 200, 15, 7))

    # 5. float similarities (negative Euclidean distance of uniform points), stored as bits
    p = rng.rand(60, 3)
    s = -np.sqrt(-neg_sq(p))
    cases.append(("uniform3d_n60_float_global_median", {"bits": bits(s)},
                  {"kind": "global_median"}, 0.5, 200, 15, 0))

    # 6. non-converging: damping 0.5, too few iterations to settle (exemplars still returned)
    p = rng.rand(50, 2)
    s = neg_sq(p)
    cases.append(("uniform2d_n50_not_converged", {"bits": bits(s)},
                  {"kind": "global_median"}, 0.5, 20, 15, 0))

    # 7. non-converging, no exemplar after 1 iteration (labels all -1 in scikit-learn)
    cases.append(("uniform2d_n50_no_exemplar", {"bits": bits(s)},
                  {"kind": "global_median"}, 0.5, 1, 1, 0))

    for name, data, preference, damping, max_iter, conv, seed in cases:
        if "points" in data:
            s = neg_sq(np.array(data["points"]))
        else:
            raw = [struct.unpack("<d", struct.pack("<Q", int(b, 16)))[0] for b in data["bits"]]
            n = int(round(len(raw) ** 0.5))
            s = np.array(raw).reshape(n, n)
        expected = run(s, preference, damping, max_iter, conv, seed)
        case = {
            "name": name,
            "generator": f"benches/peers/affinity_golden.py, scikit-learn {sklearn.__version__}, numpy {np.__version__}",
            **data,
            "preference": preference,
            "damping": damping,
            "max_iter": max_iter,
            "convergence_iter": conv,
            "random_state": seed,
            "expected": expected,
        }
        with open(os.path.join(out_dir, name + ".json"), "w") as f:
            json.dump(case, f)
        print(name, "clusters", len(expected["exemplars"]), "n_iter", expected["n_iter"],
              "converged", expected["converged"])


if __name__ == "__main__":
    main()
