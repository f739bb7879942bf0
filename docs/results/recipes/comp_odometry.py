"""The tables of docs/results/odometry.md that a repository command gives in reasonable time:
`wipdr eval` on the five ILC floors with the default motion source (steps) and with the
learned one held out (`odometry = "learned"`, `--odometry-holdout fixtures/odometry/lofo`:
each floor runs the network `odometry-train lofo` trained on the other four), every scheme,
causal and offline; and on the IPIN logfiles (other phones, another building: the shipped
network, held out), every scheme there. The training runs themselves (`tools/odometry-train`,
about 30 minutes) are in docs/experiments.md."""

import sys

from regenerate import ilc_floors, table

from comp_common import config_file, row

FLOORS = ["site1/F1", "site1/F2", "site2/F1", "site2/F2", "site2/F3"]

# The leave-one-floor-out networks (`odometry-train lofo`; `site1_F1.safetensors` never saw
# site1/F1), relative to the repository root where the commands run.
LOFO = "fixtures/odometry/lofo"


def ilc_learned(runs, offline):
    """Every scheme on the five floors with the learned source, each floor on its held-out
    network."""
    evaluation = sys.modules["recipes.evaluation"]
    args = ["eval", "--data", *ilc_floors(), "--schemes", evaluation.SCHEMES,
            "--config", config_file('odometry = "learned"\n'), "--odometry-holdout", LOFO]
    if offline:
        args += ["--offline"]
    return runs.wipdr_json(*args)


@table("odometry-motion")
def motion(runs):
    """The motion source's per-segment displacement error, steps against learned (held out)."""
    evaluation = sys.modules["recipes.evaluation"]
    steps = evaluation.ilc(runs)["motion"]["summaries"]
    learned = ilc_learned(runs, False)["motion"]["summaries"]
    out = ["| floor | segments | steps mean / median (m) | learned, held out, mean / median (m) "
           "| learned: truth in its 95 % ellipse |",
           "| --- | --- | --- | --- | --- |"]
    for f in FLOORS + ["pooled"]:
        s, l = steps[f], learned[f]
        assert s["segments"] == l["segments"], f
        b = "**" if f == "pooled" else ""
        sb = "**" if s["mean_m"] <= l["mean_m"] else ""
        lb = "**" if l["mean_m"] < s["mean_m"] else ""
        if f != "pooled":
            sb = lb = ""
        out.append(row(f"{b}{f}{b}", s["segments"], f"{sb}{s['mean_m']:.3f}{sb} / {s['median_m']:.3f}",
                       f"{lb}{l['mean_m']:.3f}{lb} / {l['median_m']:.3f}", inside(l)))
    return "\n".join(out)


@table("odometry-ilc-fused")
def ilc_fused(runs):
    """Every scheme on the five floors with steps and with the learned source held out:
    pooled mean / p95 (m), causal and offline."""
    evaluation = sys.modules["recipes.evaluation"]
    docs = [(evaluation.ilc(runs), ilc_learned(runs, False)),
            (evaluation.ilc(runs, True), ilc_learned(runs, True))]
    out = ["| scheme | causal, steps | causal, learned held out | offline, steps "
           "| offline, learned held out |",
           "| --- | --- | --- | --- | --- |"]
    for name in evaluation.ORDER:
        if name == "wifi":
            continue
        cells = [name]
        for steps, learned in docs:
            if name == "pdr" and steps is docs[1][0]:
                cells += ["(causal)", "(causal)"]
                continue
            a, b = steps["pooled"][name], learned["pooled"][name]
            cells += better_bold(a["mean"], b["mean"], f" / {a['p95']:.2f}", f" / {b['p95']:.2f}")
        out.append(row(*cells))
    return "\n".join(out)


def better_bold(steps, learned, steps_rest="", learned_rest=""):
    """Two cells, `steps` and `learned` with two decimals, each followed by its `rest`; the
    smaller of the two in bold (the steps on a tie)."""
    bold = sys.modules["recipes.evaluation"].bold
    return [bold(f"{steps:.2f}", steps <= learned) + steps_rest,
            bold(f"{learned:.2f}", learned < steps) + learned_rest]


def inside(summary):
    """The share of segments inside the learned 95 % ellipse, or `-`."""
    share = summary.get("inside_95")
    return "-" if share is None else f"{100 * share:.1f} %"


def ipin_runs(runs):
    """The IPIN evaluations of every scheme, causal and offline, with steps (the runs of
    accuracy.md's IPIN table, shared) and with the learned source."""
    evaluation = sys.modules["recipes.evaluation"]
    learned = ["--config", config_file('odometry = "learned"\n')]
    return (evaluation.ipin(runs), evaluation.ipin(runs, True),
            evaluation.ipin(runs, False, *learned), evaluation.ipin(runs, True, *learned))


@table("odometry-ipin-motion")
def ipin_motion(runs):
    """The motion source's per-segment displacement error on the IPIN logfiles (held out)."""
    steps, _, learned, _ = ipin_runs(runs)
    s, l = steps["motion"]["summaries"]["pooled"], learned["motion"]["summaries"]["pooled"]
    assert s["segments"] == l["segments"]
    out = ["| data | segments | mean length (m) | steps mean / median (m) "
           "| learned, held out, mean / median (m) | learned: truth in its 95 % ellipse |",
           "| --- | --- | --- | --- | --- | --- |"]
    sb, lb = ("**", "") if s["mean_m"] <= l["mean_m"] else ("", "**")
    out.append(row("IPIN 2023, 29 logfiles", s["segments"], f"{s['mean_length_m']:.2f}",
                   f"{sb}{s['mean_m']:.3f}{sb} / {s['median_m']:.3f}",
                   f"{lb}{l['mean_m']:.3f}{lb} / {l['median_m']:.3f}", inside(l)))
    return "\n".join(out)


@table("odometry-ipin-fused")
def ipin_fused(runs):
    """Every scheme on the IPIN logfiles with steps and with the learned source (EvAAL)."""
    evaluation = sys.modules["recipes.evaluation"]
    sc, so, lc, lo = ipin_runs(runs)
    out = ["| scheme | causal EvAAL, steps | causal EvAAL, learned | offline EvAAL, steps "
           "| offline EvAAL, learned |",
           "| --- | --- | --- | --- | --- |"]
    for name in evaluation.ORDER:
        if name == "wifi":
            continue
        cells = [name]
        for steps, learned in ((sc, lc), (so, lo)):
            a, b = steps["pooled"][name]["evaal"], learned["pooled"][name]["evaal"]
            if name == "pdr" and steps is so:
                cells += ["(causal)", "(causal)"]
                continue
            cells += better_bold(a, b)
        out.append(row(*cells))
    return "\n".join(out)
