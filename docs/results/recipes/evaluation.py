"""Recipes of the evaluation tables: accuracy.md, likelihood.md, floors.md, ipin.md,
fusion-real.md, static-start.md (docs/results/regenerate.py). Run times: README.md,
"Evaluation tables".

The five-floor and IPIN evaluations of every scheme (causal and offline) run once each and
feed every table that reads them (same argument list, one run).
"""

import hashlib
import json
import re
import statistics
from pathlib import Path

import regenerate
from regenerate import table

SCHEMES = "wifi,pdr,ekf,aekf,akf,rkf,arkf,aws,tcpf,pf,apf,rof,pmf"
ORDER = SCHEMES.split(",")
FUSED = [s for s in ORDER if s not in ("wifi", "pdr")]
K95 = 2.4477  # the 95 % radius of a circular Gaussian in sd units (RADIUS_95_PER_SD)


# ---------------------------------------------------------------- runs


def ipin_dir():
    return str(regenerate.data_root() / "ipin2023")


def ilc_sites():
    d = regenerate.data_root() / "ilc20"
    return [str(d / "site1"), str(d / "site2")]


def ilc(runs, offline=False):
    """`wipdr eval --data <five floors> --schemes S [--offline]`."""
    return runs.wipdr_json("eval", "--data", *regenerate.ilc_floors(), "--schemes", SCHEMES,
                           *(["--offline"] if offline else []))


def ipin(runs, offline=False, *extra):
    """`wipdr eval --data $WIPDR_DATA/ipin2023 --schemes S [--offline]`."""
    return runs.wipdr_json("eval", "--data", ipin_dir(), "--schemes", SCHEMES,
                           *(["--offline"] if offline else []), *extra)


def sites(runs):
    """`wipdr eval --data $WIPDR_DATA/ilc20/site1 $WIPDR_DATA/ilc20/site2 --schemes S`."""
    return runs.wipdr_json("eval", "--data", *ilc_sites(), "--schemes", SCHEMES)


def config_file(text):
    """A config file holding `text` under target/results/ (named by its content)."""
    path = regenerate.WORK / f"config-{hashlib.sha256(text.encode()).hexdigest()[:12]}.toml"
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return str(path)


def json_command(runs, argv):
    """Runs `argv` + `--json FILE` once (like `runs.wipdr_json` for any command line)."""
    key = hashlib.sha256("\0".join(map(str, argv)).encode()).hexdigest()[:16]
    path = regenerate.WORK / f"{key}.json"
    runs.command([*argv, "--json", str(path)], outputs=[path])
    return json.loads(path.read_text())


def walk_folds(runs, offline=False):
    """`bash docs/results/ipin_walk_folds.sh $WIPDR_DATA/ipin2023 -- --schemes S [--offline]`."""
    return json_command(runs, ["env", f"WIPDR_BIN={runs.program}", "bash",
                               "docs/results/ipin_walk_folds.sh", ipin_dir(), "--",
                               "--schemes", SCHEMES, *(["--offline"] if offline else [])])


# ---------------------------------------------------------------- formatting


def f2(x):
    return "-" if x is None else f"{x:.2f}"


def pct(x):
    return "-" if x is None else f"{100 * x:.1f} %"


def n_(n):
    return f"{n:,}"


def bold(text, on):
    return f"**{text}**" if on else text


def rows(header, body):
    out = ["| " + " | ".join(header) + " |", "| " + " | ".join("---" for _ in header) + " |"]
    out += ["| " + " | ".join(r) + " |" for r in body]
    return "\n".join(out) + "\n"


def floor_name(label):
    """`site1/F1` from a floor folder's label (the last two path components)."""
    parts = Path(label).parts
    return "/".join(parts[-2:]) if len(parts) >= 2 else label


def best(doc, key, schemes=FUSED):
    """The scheme of `schemes` with the lowest pooled `key`."""
    return min((s for s in schemes if s in doc["pooled"]), key=lambda s: doc["pooled"][s][key])


def same(a, b):
    keys = ("mean", "p75", "p95", "evaal", "radius_95_coverage", "floor_hit_rate")
    return all(a.get(k) == b.get(k) for k in keys)


def label(s):
    return "pdr (true start)" if s == "pdr" else s


def worst_wrong_floor_s(doc):
    """Per scheme, the longest a walk spent on a wrong floor, seconds
    (`WalkScore::longest_wrong_floor_ms`: from the first waypoint of a run scored on a wrong
    floor to the next one scored right)."""
    worst = {}
    for w in doc["walks"]:
        errors = w["errors"]
        longest = 0
        if any(e[2] is not None for e in errors):
            start = None
            for t, _, fe in errors:
                if fe != 0 and start is None:
                    start = t
                elif fe == 0 and start is not None:
                    longest = max(longest, t - start)
                    start = None
            if start is not None:
                longest = max(longest, errors[-1][0] - start)
        worst[w["scheme"]] = max(worst.get(w["scheme"], 0), longest)
    return {s: ms / 1000.0 for s, ms in worst.items()}


# ---------------------------------------------------------------- accuracy.md


@table("eval-ilc-pooled")
def ilc_pooled(runs):
    """Five ILC floors pooled, every scheme, causal and offline (accuracy.md)."""
    c, o = ilc(runs), ilc(runs, offline=True)
    bc, bo = best(c, "mean"), best(o, "mean")
    body = []
    for s in ORDER:
        pc, po = c["pooled"][s], o["pooled"][s]
        if s == "pdr":
            body.append([label(s), f"{f2(pc['mean'])} / {f2(pc['p95'])}", "-", "(causal)", "-"])
            continue
        body.append([
            bold(s, s == bc),
            bold(f"{f2(pc['mean'])} / {f2(pc['p95'])}", s == bc),
            bold(pct(pc.get("radius_95_coverage")), s == bc and pc.get("radius_95_coverage") is not None),
            bold(f"{f2(po['mean'])} / {f2(po['p95'])}", s == bo),
            pct(po.get("radius_95_coverage")),
        ])
    return rows(["scheme", "causal mean / p95", "causal r95", "offline mean / p95", "offline r95"], body)


@table("eval-ilc-best-floors")
def ilc_best_floors(runs):
    """The best causal scheme per floor, causal and offline (accuracy.md)."""
    c, o = ilc(runs), ilc(runs, offline=True)
    s = best(c, "mean")
    body = []
    for floor in c["floors"]:
        fc, fo = c["floors"][floor][s], o["floors"][floor][s]
        body.append([floor_name(floor), n_(fc["count"]), f"{f2(fc['mean'])} / {f2(fc['p95'])}",
                     pct(fc.get("radius_95_coverage")), f"{f2(fo['mean'])} / {f2(fo['p95'])}",
                     pct(fo.get("radius_95_coverage"))])
    pc, po = c["pooled"][s], o["pooled"][s]
    body.append(["pooled", n_(pc["count"]), f"{f2(pc['mean'])} / {f2(pc['p95'])}",
                 pct(pc.get("radius_95_coverage")), f"{f2(po['mean'])} / {f2(po['p95'])}",
                 pct(po.get("radius_95_coverage"))])
    return rows([f"`{s}`, floor", "points", "causal mean / p95", "causal r95",
                 "offline mean / p95", "offline r95"], body)


def ipin_rows(c, o, schemes):
    """Scheme rows of an IPIN table; `rkf` / `arkf` left out where they equal `ekf` / `akf`."""
    out = []
    for s in schemes:
        twin = {"rkf": "ekf", "arkf": "akf"}.get(s)
        if twin and same(c["pooled"][s], c["pooled"][twin]) and (
                o is None or same(o["pooled"][s], o["pooled"][twin])):
            continue
        out.append(s)
    return out


@table("eval-ipin")
def ipin_table(runs):
    """IPIN 2023 logfiles, leave-one-route-out, every scheme, causal and offline (accuracy.md)."""
    c, o = ipin(runs), ipin(runs, True)
    bc, bo = best(c, "evaal"), best(o, "evaal")
    body = []
    for s in ipin_rows(c, o, ORDER):
        pc, po = c["pooled"][s], o["pooled"][s]
        causal = f"{f2(pc['mean'])} / {f2(pc['p75'])} / {f2(pc['evaal'])}"
        if s == "pdr":
            body.append([label(s), causal, "-", "(causal)", "-"])
            continue
        body.append([bold(s, s == bc), bold(causal, s == bc), pct(pc.get("radius_95_coverage")),
                     bold(f"{f2(po['mean'])} / {f2(po['evaal'])}", s == bo),
                     pct(po.get("radius_95_coverage"))])
    return rows(["scheme", "causal mean / p75 / EvAAL", "causal r95", "offline mean / EvAAL",
                 "offline r95"], body)


@table("eval-ipin-twins")
def ipin_twins(runs):
    """Whether `rkf` / `arkf` equal `ekf` / `akf` on IPIN and ILC (accuracy.md)."""
    c, o, i, io = ilc(runs), ilc(runs, True), ipin(runs), ipin(runs, True)
    body = []
    for s, twin in (("rkf", "ekf"), ("arkf", "akf")):
        body.append([f"`{s}` = `{twin}`"] + [
            "yes" if same(d["pooled"][s], d["pooled"][twin]) else "no" for d in (c, o, i, io)])
    return rows(["", "ILC causal", "ILC offline", "IPIN causal", "IPIN offline"], body)


@table("eval-ilc-sites")
def ilc_sites_table(runs):
    """ILC sites read as buildings, every scheme, causal (accuracy.md)."""
    d = sites(runs)
    b = best(d, "evaal")
    body = []
    for s in ORDER:
        p = d["pooled"][s]
        body.append([bold(label(s), s == b), bold(f"{f2(p['mean'])} / {f2(p['p95'])} / {f2(p['evaal'])}", s == b),
                     pct(p.get("radius_95_coverage")), pct(p.get("floor_hit_rate"))])
    return rows(["scheme", "mean / p95 / EvAAL", "r95", "floors"], body)


@table("eval-ipin-walk-folds")
def ipin_walk_folds(runs):
    """IPIN with each walk its own route (ipin_walk_folds.sh), causal and offline (accuracy.md)."""
    c, o = walk_folds(runs), walk_folds(runs, True)
    bc, bo = best(c, "evaal"), best(o, "evaal")
    body = []
    for s in ipin_rows(c, o, ORDER):
        pc, po = c["pooled"][s], o["pooled"][s]
        causal = f"{f2(pc['mean'])} / {f2(pc['p75'])} / {bold(f2(pc['evaal']), s == bc)}"
        if s == "pdr":
            body.append([label(s), causal, "-", "(causal)"])
            continue
        body.append([s, causal, pct(pc.get("radius_95_coverage")),
                     f"{f2(po['mean'])} / {f2(po['p75'])} / {bold(f2(po['evaal']), s == bo)}"])
    return rows(["scheme", "causal", "causal r95", "offline"], body)


def radius_by_coverage(doc, scheme):
    """(bin label, inside, points) rows and the median 95 % radius, as
    docs/results/radius_by_coverage.py computes them."""
    edges = [3.0, 6.0, 12.0]
    bins = [[0, 0] for _ in range(len(edges) + 1)]
    radii = []
    for w in doc["walks"]:
        if w["scheme"] != scheme or not w.get("sd_m"):
            continue
        for err, sd, cov in zip(w["errors"], w["sd_m"], w["coverage_m"]):
            radii.append(K95 * sd)
            i = next((i for i, e in enumerate(edges) if cov < e), len(edges))
            bins[i][0] += err[1] <= K95 * sd
            bins[i][1] += 1
    return bins, statistics.median(radii)


@table("eval-radius-coverage")
def radius_coverage(runs):
    """`pmf`'s 95 % radius by the truth's distance to coverage (accuracy.md)."""
    c, i = ilc(runs), ipin(runs)
    s = "pmf"
    (bc, mc), (bi, mi) = radius_by_coverage(c, s), radius_by_coverage(i, s)
    names = ["< 3 m", "3-6 m", "6-12 m", ">= 12 m"]
    body = []
    for k, name in enumerate(names):
        body.append([name, f"{pct(bc[k][0] / bc[k][1])} ({n_(bc[k][1])} points)",
                     f"{pct(bi[k][0] / bi[k][1])} ({n_(bi[k][1])})"])
    body.append(["all", bold(pct(sum(b[0] for b in bc) / sum(b[1] for b in bc)), True),
                 bold(pct(sum(b[0] for b in bi) / sum(b[1] for b in bi)), True)])
    body.append(["median 95 % radius", f"{mc:.1f} m", f"{mi:.1f} m"])
    return rows(["distance to coverage", "ILC five floors", "IPIN"], body)


# ---------------------------------------------------------------- likelihood.md

NO_LIKELIHOOD = "[schemes.pmf]\nwifi_likelihood = false\n"


@table("eval-likelihood-switch")
def likelihood_switch(runs):
    """`pmf` with and without the scan likelihood (`wifi_likelihood = false`), ILC and IPIN."""
    off = config_file(NO_LIKELIHOOD)
    on_c, on_o, on_i, on_io = ilc(runs), ilc(runs, True), ipin(runs), ipin(runs, True)
    floors = regenerate.ilc_floors()
    off_c = runs.wipdr_json("eval", "--data", *floors, "--schemes", "pmf", "--config", off)
    off_o = runs.wipdr_json("eval", "--data", *floors, "--schemes", "pmf", "--config", off, "--offline")
    off_i = runs.wipdr_json("eval", "--data", ipin_dir(), "--schemes", "pmf", "--config", off)
    off_io = runs.wipdr_json("eval", "--data", ipin_dir(), "--schemes", "pmf", "--config", off, "--offline")

    def better(a, b, key):
        """Bold the lower of two values of `key` (`pmf`, pooled)."""
        x, y = a["pooled"]["pmf"][key], b["pooled"]["pmf"][key]
        return x < y, y < x

    body = []
    for name, a, b, k2, key in (
            ("ILC causal `pmf` mean / p95", off_c, on_c, "p95", "mean"),
            ("ILC causal `pmf` p50 / p75", off_c, on_c, None, None),
            ("ILC offline `pmf` mean / p95", off_o, on_o, "p95", "mean"),
            ("IPIN causal `pmf` mean / EvAAL", off_i, on_i, "evaal", "evaal"),
            ("IPIN offline `pmf` mean / EvAAL", off_io, on_io, "evaal", "evaal")):
        if k2 is None:
            pa, pb = a["pooled"]["pmf"], b["pooled"]["pmf"]
            body.append([name, f"{f2(pa['p50'])} / {f2(pa['p75'])} m", f"{f2(pb['p50'])} / {f2(pb['p75'])} m"])
            continue
        pa, pb = a["pooled"]["pmf"], b["pooled"]["pmf"]
        ba, bb = better(a, b, key)
        body.append([name, bold(f"{f2(pa['mean'])} / {f2(pa[k2])} m", ba),
                     bold(f"{f2(pb['mean'])} / {f2(pb[k2])} m", bb)])
    ra, rb = off_c["pooled"]["pmf"]["radius_95_coverage"], on_c["pooled"]["pmf"]["radius_95_coverage"]
    body.append(["ILC `pmf` radius holds the truth (r95)", pct(ra), pct(rb)])
    return rows(["", "`wifi_likelihood = false`", "default (`true`)"], body)


@table("eval-likelihood-calibration")
def likelihood_calibration(runs):
    """Where the truth falls in each scored scan's likelihood, per floor (likelihood.md)."""
    c, i = ilc(runs), ipin(runs)
    body = []
    for floor, m in c["scan_likelihood"].items():
        if floor == "pooled":
            continue
        body.append([floor_name(floor), n_(m["scans"]), pct(m["region_95_holds"]),
                     f"{m['rank_median']:,.0f}", f"{m['rank_p90']:,.0f}"])
    m = c["scan_likelihood"]["pooled"]
    body.append(["pooled", n_(m["scans"]), bold(pct(m["region_95_holds"]), True),
                 f"{m['rank_median']:,.0f}", f"{m['rank_p90']:,.0f}"])
    m = i["scan_likelihood"]["pooled"]
    body.append(["IPIN logfiles", n_(m["scans"]), pct(m["region_95_holds"]),
                 f"{m['rank_median']:,.0f}", f"{m['rank_p90']:,.0f}"])
    return rows(["floor", "scans", "95 % region holds the truth", "rank median", "rank p90"], body)


# ---------------------------------------------------------------- floors.md


def floor_rows(doc):
    """Fused schemes with the same floors / EvAAL / worst share a row (`ekf, rkf`)."""
    worst = worst_wrong_floor_s(doc)
    b = best(doc, "evaal")
    groups = []
    for s in FUSED:
        p = doc["pooled"][s]
        key = (pct(p.get("floor_hit_rate")), f2(p.get("evaal")), f"{worst.get(s, 0.0):.1f} s")
        for g in groups:
            if g[1] == key:
                g[0].append(s)
                break
        else:
            groups.append(([s], key))
    body = []
    for names, key in groups:
        top = b in names
        body.append([bold(", ".join(names), top)] + [bold(k, top) for k in key])
    return rows(["scheme", "floors", "EvAAL", "worst"], body)


@table("eval-floors-ipin")
def floors_ipin(runs):
    """IPIN floors, EvAAL and the worst time on a wrong floor, every fused scheme (floors.md)."""
    return floor_rows(ipin(runs))


@table("eval-floors-sites")
def floors_sites(runs):
    """ILC sites as buildings: floors, EvAAL, worst time on a wrong floor (floors.md)."""
    return floor_rows(sites(runs))


@table("eval-floors-sites-per-site")
def floors_sites_per_site(runs):
    """ILC sites as buildings: floor hits per site, every fused scheme (floors.md)."""
    d = sites(runs)
    body = []
    for site, per in d["floors"].items():
        hits = sorted({pct(per[s].get("floor_hit_rate")) for s in FUSED})
        body.append([Path(site).name, " / ".join(hits), n_(per["pmf"]["count"])])
    return rows(["site", "floors (every fused scheme)", "points"], body)


# ---------------------------------------------------------------- ipin.md

IPIN_SETTINGS = [
    ("shipped defaults (`reference_window_min = 60`)", None),
    ("`[floor] reference_window_min = 360`", "[floor]\nreference_window_min = 360.0\n"),
    ("`[floor] reference_window_min = 1440`", "[floor]\nreference_window_min = 1440.0\n"),
    ("`[floor] reference_window_min = 0` (Wi-Fi alone)", "[floor]\nreference_window_min = 0.0\n"),
    ("`[floor] fixes_across_floors = false`", "[floor]\nfixes_across_floors = false\n"),
    ("`--config docs/configs/ipin.toml` (handling hysteresis)", "docs/configs/ipin.toml"),
]


@table("eval-ipin-settings")
def ipin_settings(runs):
    """IPIN under the floor and handling settings ipin.md discusses (causal)."""
    body = []
    for name, setting in IPIN_SETTINGS:
        if setting is None:
            d = ipin(runs)
        else:
            path = setting if setting.endswith(".toml") else config_file(setting)
            d = runs.wipdr_json("eval", "--data", ipin_dir(), "--schemes", "wifi,ekf,pmf", "--config", path)
        p = d["pooled"]
        body.append([name, f2(p["wifi"]["mean"]), f2(p["ekf"]["mean"]),
                     f"{f2(p['pmf']['mean'])} / {f2(p['pmf']['evaal'])}", pct(p["pmf"].get("floor_hit_rate"))])
    return rows(["setting", "`wifi` mean", "`ekf` mean", "`pmf` mean / EvAAL", "`pmf` floors"], body)


# ---------------------------------------------------------------- fusion-real.md

# Issue 7's reference pipeline (outside the repository), per floor mean / p95 in metres.
REFERENCE = {"site1/F1": (6.66, 13.22), "site1/F2": (6.73, 14.96), "site2/F1": (11.47, 32.23),
             "site2/F2": (26.69, 109.00), "site2/F3": (29.01, 124.32), "pooled": (12.07, 39.59)}


@table("eval-reference-check")
def reference_check(runs):
    """`docs/configs/reference.toml` against issue 7's reference pipeline (fusion-real.md)."""
    d = runs.wipdr_json("eval", "--config", "docs/configs/reference.toml", "--schemes", "wifi",
                        "--data", *regenerate.ilc_floors())
    body = []
    for floor, per in [*d["floors"].items(), ("pooled", d["pooled"])]:
        name = floor_name(floor)
        w = per["wifi"]
        ref = REFERENCE[name]
        body.append([name if name != "pooled" else f"pooled ({n_(w['count'])})",
                     f"{ref[0]:.2f} / {ref[1]:.2f}", f"{f2(w['mean'])} / {f2(w['p95'])}"])
    return rows(["floor", "reference mean / p95", "wipdr mean / p95"], body)


# ---------------------------------------------------------------- static-start.md

STATIC_SCHEMES = "wifi,ekf,tcpf,pf,rof,pmf"


@table("eval-static-start")
def static_start(runs):
    """The first 20 m of every walk, with and without the static start (static-start.md)."""
    plain = config_file("score_first_m = 20.0\n")
    static = config_file("score_first_m = 20.0\n[static_start]\ngross_m = 10.0\n")
    floors = regenerate.ilc_floors()
    a = runs.wipdr_json("eval", "--config", plain, "--schemes", STATIC_SCHEMES, "--data", *floors)
    b = runs.wipdr_json("eval", "--config", static, "--schemes", STATIC_SCHEMES, "--data", *floors)
    body = []
    for s in STATIC_SCHEMES.split(","):
        pa, pb = a["pooled"][s], b["pooled"][s]
        body.append([s, n_(pa["count"]), f"{f2(pa['mean'])} / {f2(pa['p95'])}",
                     f"{f2(pb['mean'])} / {f2(pb['p95'])}"])
    return rows(["scheme", "points", "without: mean / p95", "with `[static_start]`: mean / p95"], body)


@table("eval-uninformed-walks")
def uninformed_walks(runs):
    """The walks whose every scored Wi-Fi error is 15 m or more, offline `pmf` (accuracy.md;
    docs/results/uninformed_walks.py's computation)."""
    d, scheme, min_m = ilc(runs, True), "pmf", 15.0
    key = lambda w: (w["floor"], w["walk"])
    wifi = {key(w): w for w in d["walks"] if w["scheme"] == "wifi"}
    fused = [w for w in d["walks"] if w["scheme"] == scheme and w["errors"]]
    total = sum(e[1] for w in fused for e in w["errors"])
    points = sum(len(w["errors"]) for w in fused)
    out_sum, out_points, out_walks, body = 0.0, 0, 0, []
    for w in sorted(fused, key=lambda w: -sum(e[1] for e in w["errors"])):
        f = wifi.get(key(w))
        if f is None or not f["errors"] or min(e[1] for e in f["errors"]) < min_m:
            continue
        s = sum(e[1] for e in w["errors"])
        out_sum += s
        out_points += len(w["errors"])
        out_walks += 1
        wifi_mean = sum(e[1] for e in f["errors"]) / len(f["errors"])
        body.append([floor_name(w["floor"]), w["walk"][:8], n_(len(w["errors"])), f"{wifi_mean:.1f}",
                     f"{s / len(w['errors']):.1f}"])
    body.append([f"these {out_walks} walks", f"{100 * out_sum / total:.1f} % of the summed error",
                 n_(out_points), "", f"{out_sum / out_points:.2f}"])
    body.append(["every other walk", "", n_(points - out_points), "",
                 bold(f"{(total - out_sum) / (points - out_points):.2f}", True)])
    body.append(["all", "", n_(points), "", f"{total / points:.2f}"])
    return rows(["floor", "walk", "points", "`wifi` mean", f"offline `{scheme}` mean"], body)


@table("eval-ipin-routes")
def ipin_routes(runs):
    """`pmf`'s IPIN error by route (ipin.md; the computation of
    docs/results/errors_by_route.py)."""
    d, scheme = ipin(runs), "pmf"
    routes = {}
    for w in d["walks"]:
        if w["scheme"] == scheme and w["errors"]:
            m = re.search(r"Trial(\d+)", w["walk"])
            routes.setdefault("Trial" + m.group(1) if m else w["walk"], []).append(w)
    total = sum(e[1] for ws in routes.values() for w in ws for e in w["errors"])
    body = []
    for route, walks in sorted(routes.items()):
        errors = [e[1] for w in walks for e in w["errors"]]
        coverage = [c for w in walks for c in w.get("coverage_m", [])]
        body.append([route, str(len(walks)), n_(len(errors)), f2(statistics.mean(errors)),
                     f"{100 * sum(errors) / total:.0f} %", f"{statistics.median(coverage):.1f}",
                     f"{100 * sum(c >= 6 for c in coverage) / len(coverage):.0f} %"])
    return rows(["route", "walks", "points", f"`{scheme}` mean", "share of the summed error",
                 "distance to coverage, median m", "points 6 m or more from coverage"], body)


# ---------------------------------------------------------------- site-model.md


@table("eval-site-model", measured=True)
def site_model(runs):
    """Site model files: points, APs, fit time, size, load time (site-model.md; measured)."""
    out = runs.command(["bash", "-c", "cargo bench -p wipdr-benches --bench site_model 2>&1"])
    fits = {m.group(1): m.groups()[1:] for m in re.finditer(
        r"site_model: (.+?): fit ([\d.]+) s, file ([\d.]+) MB \((\d+) points, (\d+) APs\)", out)}
    to_ms = {"s": 1000.0, "ms": 1.0, "µs": 0.001, "us": 0.001}
    loads = {m.group(1).strip(): f"{float(m.group(2)) * to_ms[m.group(3)]:,.0f} ms" for m in re.finditer(
        r"site_model_load/([^\n]+?)\s+time:\s+\[\S+ \S+ ([\d.]+) (\S+)", out)}
    names = {"ipin trials": "IPIN 2023, 29 logfiles"}
    body = []
    for name, (fit_s, mb, points, aps) in fits.items():
        place = names.get(name, name.replace("ilc ", "ILC "))
        body.append([place, n_(int(points)), n_(int(aps)), f"{fit_s} s", f"{mb} MB", loads.get(name, "-")])
    return rows(["place", "reference points", "APs", "fit", "file", "load (criterion estimate)"], body)


# ---------------------------------------------------------------- propagation.md


def propagation_example(runs):
    """`cargo run --release -p wipdr-eval --example propagation`, parsed: per floor, the
    uncensored fit's figures and its leave-out checks."""
    out = runs.command(["cargo", "run", "--release", "-q", "-p", "wipdr-eval", "--example", "propagation"])
    floors = {}
    for block in re.split(r"^== ", out, flags=re.M)[1:]:
        name = block.split(" ", 1)[0]
        head = re.match(r"\S+ \(fold 0 training map\): (\d+) reference points, (\d+) APs", block)
        plain = block.split("-- censored_weight 1")[0]
        fit = re.search(r"fit: (\d+) models, dropped: (\d+) too few samples, \d+ degenerate, "
                        r"\d+ not finite, (\d+) rmse > (\d+) dB", plain)
        med = re.search(r"median rmse ([\d.]+) dB, median exponent ([\d.]+)", plain)
        fifth = re.search(r"leave-out every 5th point:.*?mean \|err\| model ([\d.]+) dB, "
                          r"nearest-kept-hearing-point baseline ([\d.]+) dB", plain, re.S)
        band = plain[plain.index("leave-out band"):]
        bins = {m.group(1): (m.group(2), m.group(3)) for m in re.finditer(
            r"nearest kept hearing point\s+(\d+-\d+)\s+m:\s+\d+ entries, model ([\d.]+) dB, "
            r"baseline ([\d.]+) dB", band)}
        heard = re.search(r"heard set at >= -85 dBm: [\d.]+ predicted / [\d.]+ heard APs per point "
                          r"\(trusted models\), precision ([\d.]+), recall ([\d.]+)", plain)
        floors[name] = dict(points=int(head.group(1)), aps=int(head.group(2)), models=int(fit.group(1)),
                            few=int(fit.group(2)), bad=int(fit.group(3)), bad_db=fit.group(4),
                            rmse=med.group(1), exponent=med.group(2), fifth=fifth.groups(),
                            band=bins, heard85=heard.groups())
    return floors


def better_pair(model, baseline):
    m, b = float(model), float(baseline)
    return bold(f"{model} dB", m < b), bold(f"{baseline} dB", b < m)


@table("eval-propagation-fit")
def propagation_fit(runs):
    """Per coverage-gap floor, the path-loss models fit on fold 0's training map (propagation.md)."""
    body = []
    for name, f in propagation_example(runs).items():
        body.append([name, n_(f["points"]), n_(f["aps"]), n_(f["models"]), n_(f["few"]),
                     f"{n_(f['bad'])} (> {f['bad_db']} dB)", f"{f['rmse']} dB", f["exponent"],
                     f"{f['heard85'][0]} / {f['heard85'][1]}"])
    return rows(["floor", "training points", "APs", "models", "too few samples", "fit too poor",
                 "median fit RMSE", "median exponent", "heard at >= -85 dBm: precision / recall"], body)


@table("eval-propagation-leave-out")
def propagation_leave_out(runs):
    """Mean absolute RSS error on held-out fingerprints, model against the nearest value
    (propagation.md)."""
    floors = propagation_example(runs)
    body = []
    for label_, pick in (("every 5th fingerprint (mostly 0-8 m from the rest)", lambda f: f["fifth"]),
                         ("a 20 m band across the floor, entries 8-14 m from data", lambda f: f["band"]["8-14"]),
                         ("the same band, 14-20 m from data", lambda f: f["band"]["14-20"])):
        row = [label_]
        for f in floors.values():
            row += better_pair(*pick(f))
        body.append(row)
    header = ["held out"]
    for name in floors:
        header += [f"{name} model", f"{name} nearest value"]
    return rows(header, body)
