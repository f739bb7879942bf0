"""The tables of docs/results/papers.md: the papers' schemes with the shipped defaults and the
tuned configs (docs/configs/tuned/, written by `docs/results/papers.sh tune`), on the five ILC
floors and on the synthetic fixture floor. `docs/results/papers.sh tables` runs this recipe."""

import os

from regenerate import ROOT, ilc_floors, table

from comp_common import config_file

SCHEMES = os.environ.get("PAPERS_SCHEMES", "wifi,pdr,ekf,aekf,akf,rkf,arkf,aws,tcpf,pf,apf,rof,pmf")
# Schemes with a tuning sweep docs/sweeps/tune-<name>.toml (apf-med: MED + APF), as papers.sh.
TUNED = ["ekf", "aekf", "akf", "rkf", "arkf", "aws", "tcpf", "rof", "pf", "apf"]
MED_BASE = "docs/sweeps/med2-base.toml"
FIXTURE = "fixtures/sim/F1"


def configs():
    """(defaults config, tuned config, MED tuned config) paths."""
    tuned = "".join((ROOT / f"docs/configs/tuned/{s}.toml").read_text() for s in TUNED
                    if (ROOT / f"docs/configs/tuned/{s}.toml").exists())
    # Every scheme named by its bare tag: its defaults, written out in the JSON's config.
    defaults = "".join(f'[schemes.{s}]\nscheme = "{s}"\n\n' for s in SCHEMES.split(","))
    med_tuned = "docs/configs/tuned/apf-med.toml"
    if not (ROOT / med_tuned).exists():
        med_tuned = MED_BASE
    return config_file(defaults), config_file(tuned), med_tuned


def evals(runs):
    defaults, tuned, med_tuned = configs()
    ilc = ilc_floors()

    def ev(config, schemes, data):
        return runs.wipdr_json("eval", "--config", config, "--schemes", schemes, "--data", *data)

    return {
        "default": ev(defaults, SCHEMES, ilc),
        "tuned": ev(tuned, SCHEMES, ilc),
        "med-default": ev(MED_BASE, "wifi,apf", ilc),
        "med-tuned": ev(med_tuned, "wifi,apf", ilc),
        "fixture-default": ev(defaults, SCHEMES, [FIXTURE]),
        "fixture-tuned": ev(tuned, SCHEMES, [FIXTURE]),
    }


def fmt(s, keys):
    return " | ".join(f"{s[k]:.2f}" for k in keys)


def flat(table_, prefix=""):
    for k, v in table_.items():
        if isinstance(v, dict):
            yield from flat(v, prefix + k + ".")
        elif k != "scheme":
            yield prefix + k, v


def show(v):
    return f"{v:.4g}" if isinstance(v, float) else str(v).lower()


@table("papers-tables")
def papers_tables(runs):
    """Every table of papers.md: default and tuned configs, ILC floors and fixture floor."""
    e = evals(runs)
    pooled = {k: v["pooled"] for k, v in e.items()}
    default, tuned = pooled["default"], pooled["tuned"]
    med_default, med_tuned = pooled["med-default"], pooled["med-tuned"]
    order = SCHEMES.split(",")
    n = default["wifi"]["count"] if "wifi" in default else 0
    default_cfg = e["default"]["config"].get("schemes", {})
    tuned_cfg = e["tuned"]["config"].get("schemes", {})
    med_tuned_cfg = e["med-tuned"]["config"].get("schemes", {})

    def row(label, d, t, keys=("mean", "rms", "p95"), paper=""):
        cells = [label] + ([paper] if paper is not None else [])
        return "| " + " | ".join(cells) + f" | {fmt(d, keys)} | {fmt(t, keys)} |"

    def head(first, keys=("mean", "rms", "p95"), paper="paper (their data)"):
        cols = [first] + ([paper] if paper else [])
        cols += [f"default {k}" for k in keys] + [f"tuned {k}" for k in keys]
        return "| " + " | ".join(cols) + " |\n|" + " --- |" * len(cols)

    def scheme_row(label, s, paper):
        return row(label, default[s], tuned[s], paper=paper)

    def moved(s, tuned_table=None):
        """The fields whose tuned value differs from the default, `field default -> tuned`."""
        d = dict(flat(default_cfg.get(s.removesuffix("-med"), {})))
        t = dict(flat(tuned_table if tuned_table is not None else tuned_cfg.get(s, {})))
        if not t:
            return "(no tuned config)"
        diffs = [f"{k} {show(d.get(k))} → {show(v)}" for k, v in sorted(t.items()) if d.get(k) != v]
        return ", ".join(diffs) or "(defaults)"

    out = []
    out.append(f"Pooled over the five floors ({n} scored waypoints). Errors in metres.\n")
    out.append("### Paper 000: standard / adaptive / adaptive + robust KF\n")
    out.append(head("scheme"))
    out.append(scheme_row("standard KF (`ekf`)", "ekf", "RMS 3.444"))
    out.append(scheme_row("adaptive KF (`akf`)", "akf", "RMS 3.297"))
    out.append(scheme_row("adaptive + robust KF (`arkf`)", "arkf", "RMS 2.608"))
    out.append(scheme_row("robust KF only (`rkf`, not in 000's table)", "rkf", "-"))
    out.append("\n### Paper 001: Wi-Fi / PDR / EKF / adaptive EKF\n")
    out.append(head("scheme"))
    out.append(scheme_row("Wi-Fi (`wifi`)", "wifi", "mean 4.09"))
    out.append(scheme_row("PDR (`pdr`, true start)", "pdr", "mean 6.08"))
    out.append(scheme_row("EKF (`ekf`)", "ekf", "mean 2.74"))
    out.append(scheme_row("adaptive EKF (`aekf`)", "aekf", "mean 2.32"))
    out.append("\n### Paper 002: Wi-Fi / PDR / TCPF\n")
    out.append(head("scheme"))
    out.append(scheme_row("Wi-Fi (`wifi`)", "wifi", "mean 2.68 (improved Wi-Fi)"))
    out.append(scheme_row("PDR (`pdr`, true start)", "pdr", "-"))
    out.append(scheme_row("TCPF (`tcpf`)", "tcpf", "mean 1.36"))
    out.append("\n### Paper 004: DR / Wi-Fi / PF / MED + APF\n")
    out.append(head("scheme"))
    out.append(scheme_row("DR (`pdr`, true start)", "pdr", "8.03 / RMS 10.02"))
    out.append(scheme_row("Wi-Fi (`wifi`, single scan)", "wifi", "1.98 / RMS 2.43"))
    out.append(scheme_row("PF (`pf`)", "pf", "3.45 / RMS 4.82"))
    out.append(row("MED + APF (`apf`, `[med] window = 2`)", med_default["apf"], med_tuned["apf"],
                   paper="1.51 / RMS 1.92"))
    out.append(row("APF on single-scan Wi-Fi (`apf`)", default["apf"], tuned["apf"], paper="-"))
    out.append(row("Wi-Fi by MED (`wifi`, `[med] window = 2`)", med_default["wifi"],
                   med_tuned["wifi"], paper="-"))
    out.append("\n### All schemes\n")
    keys = ("mean", "p95")
    out.append("| scheme | default mean | default p95 | tuned mean | tuned p95 | tuned fields |")
    out.append("| --- | --- | --- | --- | --- | --- |")
    for s in order:
        if s in default and s in tuned:
            out.append(f"| `{s}` | {fmt(default[s], keys)} | {fmt(tuned[s], keys)} | {moved(s)} |")
    out.append(f"| `apf` + MED | {fmt(med_default['apf'], keys)} | {fmt(med_tuned['apf'], keys)} "
               f"| {moved('apf-med', med_tuned_cfg.get('apf', {}))} |")
    fx_default, fx_tuned = pooled["fixture-default"], pooled["fixture-tuned"]
    out.append("\n### Tuned on the five floors, checked on a floor not tuned on\n")
    out.append("The synthetic fixture floor (`fixtures/sim/F1`, 10 walks, its own protocol run) was not "
               "used for tuning: a tuned config that only fits the five ILC floors shows here.\n")
    out.append("| scheme | ILC default | ILC tuned | fixture default | fixture tuned |")
    out.append("| --- | --- | --- | --- | --- |")
    for s in order:
        if all(s in t for t in (default, tuned, fx_default, fx_tuned)):
            out.append(f"| `{s}` | {default[s]['mean']:.2f} / {default[s]['p95']:.2f} | "
                       f"{tuned[s]['mean']:.2f} / {tuned[s]['p95']:.2f} | "
                       f"{fx_default[s]['mean']:.2f} / {fx_default[s]['p95']:.2f} | "
                       f"{fx_tuned[s]['mean']:.2f} / {fx_tuned[s]['p95']:.2f} |")
    out.append("\n(mean / p95, metres)")
    return "\n".join(out)
