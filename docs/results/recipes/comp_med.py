"""The table of docs/results/med-shared-ap.md: MED (paper 004) with the Euclidean and the
shared-AP distance against single-scan matching, `wipdr eval` on the five ILC floors."""

from regenerate import ilc_floors, table

from comp_common import mp, row


def ev(runs, config, schemes="wifi,apf,pmf"):
    args = ["eval", "--schemes", schemes, "--data", *ilc_floors()]
    if config:
        args += ["--config", config]
    return runs.wipdr_json(*args)["pooled"]


@table("med-shared-ap")
def med_shared_ap(runs):
    """wifi / apf / pmf with MED Euclidean, MED shared-AP and single scans (bold: best of the row)."""
    med_euclid = ev(runs, "docs/configs/tuned/apf-med.toml")
    med_shared = ev(runs, "docs/configs/med-shared-ap.toml")
    single = ev(runs, None)
    tuned_apf = ev(runs, "docs/configs/tuned/apf.toml", "wifi,apf")
    out = ["| scheme | MED Euclidean (`tuned/apf-med.toml`) | MED shared-AP (`med-shared-ap.toml`) | single scan (defaults) |",
           "| --- | --- | --- | --- |"]
    for s, label in [("wifi", "`wifi`"), ("apf", "`apf` (tuned for Euclidean MED)"),
                     ("pmf", "`pmf` (default parameters)")]:
        cols = [med_euclid[s], med_shared[s], single[s]]
        best = min(range(3), key=lambda i: cols[i]["mean"])
        cells = [f"**{mp(c)}**" if i == best else mp(c) for i, c in enumerate(cols)]
        if s == "apf":
            cells[2] += f" (default), {mp(tuned_apf['apf'])} (`tuned/apf.toml`)"
        out.append(row(label, *cells))
    return "\n".join(out)
