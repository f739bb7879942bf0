"""Tables of docs/results/clustering.md: `wipdr cluster`, cluster search and the AP index
(`wipdr fingerprint-eval` on the benchmarks, `wipdr eval` on the five ILC floors)."""

import json

from regenerate import data_root, ilc_floors, table

from comp_common import config_file, pct, row


def dataset(name):
    return str(data_root() / "fingerprint" / name)


CLUSTER_RUNS = [("DSI1", "mixdis", None), ("DSI1", "signal", None), ("LIB1", "mixdis", "median")]


@table("cluster-runs")
def cluster_runs(runs):
    """`wipdr cluster --json` on DSI1 / LIB1 train.csv."""
    out = ["| dataset | similarity | preference | fingerprints | clusters | iterations | status | largest / smallest cluster |",
           "| --- | --- | --- | ---: | ---: | ---: | --- | --- |"]
    for d, sim, pref in CLUSTER_RUNS:
        argv = ["wipdr", "cluster", "--dataset", dataset(d), "--similarity", sim, "--json"]
        if pref:
            argv += ["--preference", pref]
        r = json.loads(runs.command(argv))
        out.append(f"| {d} | {sim} | {pref or 'row median (default)'} | {r['n']} | {r['clusters']} | "
                   f"{r['iterations']} | {r['status']} | {max(r['sizes'])} / {min(r['sizes'])} |")
    return "\n".join(out)


# (--matcher value, label, shown for every dataset or only TUT1)
BENCH = [
    ("wknn", "wknn", True),
    ("apc", "apc (paper: MixDis, 1 cluster)", True),
    ('kind = "apc", similarity = "signal", clusters_searched = 3', "apc signal, 3 clusters", True),
    ('kind = "apc", method = { k_means = { mean_size = 10 } }, clusters_searched = 3',
     "apc K-means (size 10), 3 clusters", True),
    ("apindex", "apindex (paper: top 2, -85 dBm)", True),
    ('kind = "apindex", apply_threshold = false', "apindex, no threshold", False),
    ('kind = "apindex", top_offline = 3', "apindex top 3", False),
    ('kind = "apindex", top_offline = 3, apply_threshold = false', "apindex top 3, no threshold", False),
    ('kind = "apindex", top_offline = 4, apply_threshold = false', "apindex top 4, no threshold", True),
    ('kind = "apindex", top_offline = 5', "apindex top 5 (-85 dBm)", False),
    ('kind = "apindex", top_offline = 5, apply_threshold = false', "apindex top 5, no threshold", False),
]
BENCH_SETS = ["DSI1", "LIB1", "TUT1", "UJI1"]


@table("cluster-benchmarks")
def cluster_benchmarks(runs):
    """Cluster search and AP index against brute-force WKNN on DSI1, LIB1, TUT1, UJI1.
    Bold: the goal (>= 75 % fewer visited, mean at most 5 % worse than wknn) is met."""
    res = runs.wipdr_json("fingerprint-eval", "--dataset", *map(dataset, BENCH_SETS),
                          "--matcher", *[m for m, _, _ in BENCH])["results"]
    assert len(res) == len(BENCH_SETS) * len(BENCH)
    out = ["| dataset | matcher | mean 2D (m) | vs wknn | p95 (m) | visited | fewer visited |",
           "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
    for i, d in enumerate(BENCH_SETS):
        rows = res[i * len(BENCH):(i + 1) * len(BENCH)]
        base = rows[0]
        assert all(r["dataset"] == d for r in rows)
        for (spec, label, everywhere), r in zip(BENCH, rows):
            if not everywhere and d != "TUT1":
                continue
            if r is base:
                out.append(row(d, label, f"{r['mean_2d']:.2f}", "", f"{r['p95']:.2f}",
                               f"{r['visited_fraction']:.3f}", ""))
                continue
            vs = 100 * (r["mean_2d"] / base["mean_2d"] - 1)
            fewer = 100 * (1 - r["visited_fraction"])
            met = vs <= 5 and fewer >= 75
            b = "**" if met else ""
            out.append(f"| {d} | {label} | {r['mean_2d']:.2f} | {b}{pct(vs, sign=True)}{b} | "
                       f"{r['p95']:.2f} | {r['visited_fraction']:.3f} | {b}{pct(fewer)}{b} |")
    return "\n".join(out)


# The real walks: `[matcher]` tables of the eval config, merged onto the shipped default matcher
# (itself the AP index, top 4, no threshold, detection-weighted shared-AP WKNN; a table of
# another kind starts from that kind's defaults, so the brute force names the default's
# distance). The cluster search (`apc`) is left out: affinity propagation on every fold's map
# takes more than 5 minutes a run here (its figures: docs/experiments.md).
SHIPPED_METRIC = 'metric = { kind = "shared_ap", lambda = 80.0, detection_mid_db = 20.0 }'
WALK_MATCHERS = [
    ("brute force (WKNN over every point, the default's distance)", f'kind = "wknn"\n{SHIPPED_METRIC}'),
    ("apindex top 4, no threshold (the shipped default)", None),
    ("apindex top 4, the paper's thresholds (-85 / -75 dBm)", 'kind = "apindex"\napply_threshold = true'),
    ("apindex, the paper's settings (top 2, -85 / -75 dBm)",
     'kind = "apindex"\ntop_offline = 2\napply_threshold = true'),
]


def walk_eval(runs, matcher, schemes):
    args = ["eval", "--schemes", schemes, "--data", *ilc_floors()]
    if matcher:
        args += ["--config", config_file(f"[matcher]\n{matcher}\n")]
    return runs.wipdr_json(*args)["pooled"]


@table("cluster-walks")
def cluster_walks(runs):
    """The AP index (shipped and paper settings) against brute force on the five ILC floors, wifi and rof."""
    out = ["| matcher (`[matcher]` of the eval config) | wifi mean / p95 | rof mean / p95 |",
           "| --- | --- | --- |"]
    for label, matcher in WALK_MATCHERS:
        p = walk_eval(runs, matcher, "wifi,rof")
        out.append(f"| {label} | {p['wifi']['mean']:.2f} / {p['wifi']['p95']:.2f} | "
                   f"{p['rof']['mean']:.2f} / {p['rof']['p95']:.2f} |")
    return "\n".join(out)
