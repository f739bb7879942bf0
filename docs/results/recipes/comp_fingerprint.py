"""Tables of docs/results/fingerprint.md: `wipdr fingerprint-eval` on the nine public benchmarks."""

import re

from regenerate import data_root, table

from comp_common import row

DATASETS = ["DSI1", "DSI2", "LIB1", "LIB2", "TUT1", "TUT2", "TUT3", "TUT5", "UJI1"]


def datasets(names=DATASETS):
    return [str(data_root() / "fingerprint" / d) for d in names]


# scikit-learn's mean 2D error of 1-NN and distance-weighted 5-NN (issue 3's reference,
# `KNeighborsRegressor(algorithm="brute")`): an external reference, not a wipdr result.
SKLEARN = {
    "DSI1": (5.52, 5.32), "DSI2": (5.52, 4.71), "LIB1": (3.15, 2.69), "LIB2": (4.16, 3.75),
    "TUT1": (9.52, 8.10), "TUT2": (11.74, 12.31), "TUT3": (9.56, 9.19), "TUT5": (7.78, 6.74),
    "UJI1": (9.69, 9.11),
}

# The literature's figures (Torres-Sospedra et al. 2015, Montoliu et al. 2022), chosen on test.
LITERATURE = {"DSI1": "3.66 (2D)", "DSI2": "3.61 (2D)", "TUT1": "4.74 (2D)",
              "TUT2": "7.70 (2D)", "UJI1": "~6.5 (3D)"}

METRICS = {"sorensen": "Sørensen", "manhattan": "Manhattan", "euclidean": "Euclidean",
           "neyman": "Neyman", "plgd": "PLGD", "squared_euclidean": "squared Euclidean"}


def describe(config):
    """`wknn(k=15,w=2,sorensen,powed)` -> `WKNN k=15, 1/d^2, Sørensen, powed`."""
    m = re.fullmatch(r"(\w+)\((.*)\)", config)
    if not m:
        return config
    kind, parts = m.group(1), m.group(2).split(",")
    out = [kind.upper()]
    rest = []
    for p in parts:
        if p.startswith("k="):
            out[0] += f" {p}"
        elif p.startswith("w="):
            w = float(p[2:])
            rest.append("1/d" if w == 1 else f"1/d^{w:g}")
        else:
            rest.append(METRICS.get(p, p))
    return ", ".join(out + rest)


def rows_by(results):
    return {(r["dataset"], r["matcher"]): r for r in results["results"]}


@table("fingerprint-base")
def base(runs):
    """Plain NN / KNN / WKNN / WKNN 1/d^2 (k 5) on the nine benchmarks."""
    res = rows_by(runs.wipdr_json("fingerprint-eval", "--dataset", *datasets(),
                                  "--matcher", "nn", "knn", "wknn", "wknn2", "--k", "5"))
    out = ["| dataset | matcher | mean 2D | mean 3D | p50 | p75 | p95 | floor hit | scikit-learn mean 2D |",
           "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for d in DATASETS:
        for m in ["nn", "knn", "wknn", "wknn2"]:
            r = res[(d, m)]
            ref = {"nn": SKLEARN[d][0], "wknn": SKLEARN[d][1]}.get(m)
            out.append(row(d, m, *(f"{r[k]:.2f}" for k in ("mean_2d", "mean_3d", "p50", "p75", "p95")),
                           f"{r['floor_hit']:.3f}", "" if ref is None else f"{ref:.2f}"))
    return "\n".join(out)


def tuned_runs(runs):
    return rows_by(runs.wipdr_json("fingerprint-eval", "--dataset", *datasets(),
                                   "--matcher", "tuned-cv", "tuned-test"))


@table("fingerprint-tuned")
def tuned(runs):
    """The literature k-NN grid, chosen by CV on train.csv and on test.csv (~6 min)."""
    res = tuned_runs(runs)
    out = ["| dataset | selection | configuration | mean 2D | mean 3D | p50 | p95 | floor hit | literature |",
           "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |"]
    for d in DATASETS:
        cv, test = res[(d, "tuned-cv")], res[(d, "tuned-test")]
        for label, r in [("CV on train", cv), ("on test", test)]:
            config = describe(r["config"])
            if r is test and test["config"] == cv["config"]:
                config = "(same)"
            lit = LITERATURE.get(d, "") if r is cv else ""
            out.append(row(d, label, config, *(f"{r[k]:.2f}" for k in ("mean_2d", "mean_3d", "p50", "p95")),
                           f"{r['floor_hit']:.3f}", lit))
    return "\n".join(out)


CODE_VARIANT_SETS = ["DSI1", "DSI2", "LIB1", "LIB2", "TUT1", "TUT2", "TUT3", "TUT5"]


@table("fingerprint-code-variants")
def code_variants(runs):
    """The tuning grid with the reference code's Neyman / exponential variants (UJI1 left out)."""
    res = rows_by(runs.wipdr_json("fingerprint-eval", "--dataset", *datasets(CODE_VARIANT_SETS),
                                  "--matcher", "tuned-test", "tuned-cv", "--tune-code-variants"))
    by2d = rows_by(runs.wipdr_json("fingerprint-eval", "--dataset", *datasets(["TUT1"]),
                                   "--matcher", "tuned-test", "--tune-code-variants",
                                   "--tune-by", "2d"))
    plain = tuned_runs(runs)
    out = ["| dataset | selection | configuration | mean 2D | mean 3D | without the variants (mean 3D) |",
           "| --- | --- | --- | ---: | ---: | ---: |"]

    def line(d, label, r, p):
        return row(d, label, describe(r["config"]), f"{r['mean_2d']:.2f}", f"{r['mean_3d']:.2f}",
                   "" if p is None else f"{p['mean_3d']:.2f}")

    for d in CODE_VARIANT_SETS:
        for sel, label in [("tuned-test", "on test"), ("tuned-cv", "CV on train")]:
            out.append(line(d, label, res[(d, sel)], plain[(d, sel)]))
            if d == "TUT1" and sel == "tuned-test":
                out.append(line(d, "on test (2D, `--tune-by 2d`)", by2d[(d, sel)], None))
    return "\n".join(out)
