"""The table of docs/results/odometry.md that a repository command gives in reasonable time:
`wipdr eval` on the five ILC floors with the default motion source (steps) and with the shipped
learned weights (`odometry = "learned"`, trained on all five floors: in-sample). The
leave-one-floor-out training runs of `tools/odometry-train` and the fused schemes with the
learned source (four evaluations of every scheme, each over 5 minutes here) are in
docs/experiments.md."""

from regenerate import ilc_floors, table

from comp_common import config_file, row

FLOORS = ["site1/F1", "site1/F2", "site2/F1", "site2/F2", "site2/F3"]


def ev(runs, learned, offline):
    # The motion source's segment error does not depend on the schemes: `pdr` alone is enough.
    args = ["eval", "--schemes", "pdr", "--data", *ilc_floors()]
    if learned:
        args += ["--config", config_file('odometry = "learned"\n')]
    if offline:
        args += ["--offline"]
    return runs.wipdr_json(*args)


@table("odometry-motion")
def motion(runs):
    """The motion source's per-segment displacement error, steps against learned (in-sample)."""
    steps = ev(runs, False, False)["motion"]["summaries"]
    learned = ev(runs, True, False)["motion"]["summaries"]
    out = ["| floor | segments | steps mean / median (m) | learned, in-sample, mean / median (m) |",
           "| --- | --- | --- | --- |"]
    for f in FLOORS + ["pooled"]:
        s, l = steps[f], learned[f]
        assert s["segments"] == l["segments"], f
        b = "**" if f == "pooled" else ""
        sb = "**" if s["mean_m"] <= l["mean_m"] else ""
        lb = "**" if l["mean_m"] < s["mean_m"] else ""
        if f != "pooled":
            sb = lb = ""
        out.append(row(f"{b}{f}{b}", s["segments"], f"{sb}{s['mean_m']:.3f}{sb} / {s['median_m']:.3f}",
                       f"{lb}{l['mean_m']:.3f}{lb} / {l['median_m']:.3f}"))
    return "\n".join(out)
