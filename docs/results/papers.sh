#!/usr/bin/env bash
# Regenerates the papers' tables on the real walks (docs/results/papers.md).
#
#   docs/results/papers.sh tables   # evaluate default and tuned configs, rewrite the tables
#   docs/results/papers.sh tune     # run every tuning sweep, rewrite docs/configs/tuned/*.toml
#   docs/results/papers.sh all      # tune, then tables
#
# Run from anywhere; it works from the repository root. Environment:
#   WIPDR   the program (default target/release/wipdr; build it with
#           `cargo build --release -p wipdr`)
#   DATA    the ILC floors (default $WIPDR_DATA/ilc20, $WIPDR_DATA defaulting to ../shared/data)
#   WORK    scratch folder for JSON and sweep CSVs (default target/papers)
#   SCHEMES the schemes of the all-schemes table (default: every scheme)
#
#   FRESH   FRESH=1 deletes the sweep CSVs before `tune` (needed after any change to a
#           scheme's code or defaults: resumed rows would come from the old code)
#
# Sweeps resume: a stopped `tune` continues where it stopped (`--resume`). After editing a
# sweep file, delete its CSV under $WORK/sweeps/ (the header would not match).
# CPU: everything runs one command at a time (each is rayon-parallel over the cores).
set -euo pipefail
cd "$(dirname "$0")/../.."

WIPDR=${WIPDR:-target/release/wipdr}
DATA=${DATA:-${WIPDR_DATA:-../shared/data}/ilc20}
WORK=${WORK:-target/papers}
SCHEMES=${SCHEMES:-wifi,pdr,ekf,aekf,akf,rkf,arkf,aws,tcpf,pf,apf,rof,pmf}
# Schemes with a tuning sweep docs/sweeps/tune-<name>.toml; apf-med is MED + APF.
TUNED="ekf aekf akf rkf arkf aws tcpf rof pf apf apf-med"
FLOORS="$DATA/site1/F1 $DATA/site1/F2 $DATA/site2/F1 $DATA/site2/F2 $DATA/site2/F3"
MED_BASE=docs/sweeps/med2-base.toml
mode=${1:-tables}

for f in $FLOORS; do
    [ -d "$f" ] || { echo "missing floor folder $f (set DATA)" >&2; exit 1; }
done
[ -x "$WIPDR" ] || { echo "no $WIPDR: cargo build --release -p wipdr" >&2; exit 1; }
mkdir -p "$WORK/sweeps" docs/configs/tuned

base_of() { [ "$1" = apf-med ] && echo "--base $MED_BASE" || true; }

tune() {
    if [ "${FRESH:-0}" = 1 ]; then
        for s in $TUNED; do rm -f "$WORK/sweeps/$s.csv" "$WORK/sweeps/$s.best.toml"; done
    fi
    for s in $TUNED; do
        echo "== sweep $s"
        # shellcheck disable=SC2046
        "$WIPDR" sweep --config "docs/sweeps/tune-$s.toml" $(base_of "$s") --data $FLOORS \
            --out "$WORK/sweeps/$s.csv" --resume | tail -n 8
    done
    echo "== choosing the tuned configs"
    python3 - "$WORK" $TUNED <<'PY'
# For each sweep: the raw best config, and the pick written to docs/configs/tuned/<s>.toml.
# The pick is not the raw best but the config whose neighbourhood is best: the mean of its
# own objective and that of its 3 nearest configs of the sweep (parameters scaled to [0, 1],
# log-scaled where the sweep samples in log space). That prefers flat regions over a lucky
# knife-edge point; both are printed.
import csv, json, math, sys, tomllib

work, names = sys.argv[1], sys.argv[2:]
summary = {}
for name in names:
    spec = tomllib.load(open(f"docs/sweeps/tune-{name}.toml", "rb"))
    scheme = spec["scheme"]
    rows = list(csv.DictReader(open(f"{work}/sweeps/{name}.csv")))
    if not rows:
        print(f"{name}: no rows", file=sys.stderr)
        continue
    ranges = spec.get("random", {}).get("ranges", {})
    grid = spec.get("grid", {})

    def unit(path, v):
        if path in ranges:
            r = ranges[path]
            lo, hi, x = r["min"], r["max"], float(v)
            if r.get("log"):
                lo, hi, x = math.log(lo), math.log(hi), math.log(x)
            return 0.0 if hi == lo else (x - lo) / (hi - lo)
        values = grid[path]
        i = values.index(v) if v in values else 0
        return 0.0 if len(values) < 2 else i / (len(values) - 1)

    points = []
    for r in rows:
        params = json.loads(r["id"])
        coords = [unit(p, v) for p, v in sorted(params.items())]
        points.append((params, coords, float(r["objective"]), r))
    k = min(3, len(points) - 1)
    scored = []
    for i, (params, coords, obj, r) in enumerate(points):
        dists = sorted(
            (math.dist(coords, other[1]), j) for j, other in enumerate(points) if j != i
        )
        neighbours = [points[j][2] for _, j in dists[:k]]
        smooth = (obj + sum(neighbours)) / (1 + len(neighbours))
        scored.append((smooth, obj, i))
    raw = min(points, key=lambda p: p[2])
    smooth, _, pick_i = min(scored)
    params, _, obj, row = points[pick_i]
    raw_smooth = next(s for s, _, i in scored if points[i] is raw)

    # The scheme's table holds only the tuned fields; the rest keep the shipped defaults.
    tables = {(): {}}
    for path, v in params.items():
        parts = path.split(".")
        assert parts[0] == "fuser", path
        tables.setdefault(tuple(parts[1:-1]), {})[parts[-1]] = v

    def toml_value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        return json.dumps(v)

    out = [
        f"# Tuned `{scheme}`{' with MED (paper 004)' if name == 'apf-med' else ''}: written by",
        f"# docs/results/papers.sh tune from docs/sweeps/tune-{name}.toml (config #{row['index']}"
        f" of {len(rows)}).",
        "# Chosen for its neighbourhood (its own and its 3 nearest configs' mean), not only its",
        f"# own: pooled mean {float(row['mean']):.2f} m, p95 {float(row['p95']):.2f} m, "
        f"neighbourhood {smooth:.2f} m on the five ILC floors",
        f"# (raw best #{raw[3]['index']}: mean {float(raw[3]['mean']):.2f}, p95 "
        f"{float(raw[3]['p95']):.2f}, neighbourhood {raw_smooth:.2f}).",
        "# Only the tuned fields are listed; the others keep their defaults.",
    ]
    if name == "apf-med":
        out += ["", "[med]", "window = 2"]
    for sub in sorted(tables):
        head = ".".join(("schemes", scheme) + sub)
        out += ["", f"[{head}]"]
        if not sub:
            out.append(f'scheme = "{scheme}"')
        for key in sorted(tables[sub]):
            out.append(f"{key} = {toml_value(tables[sub][key])}")
    open(f"docs/configs/tuned/{name}.toml", "w").write("\n".join(out) + "\n")
    summary[name] = {
        "configs": len(rows),
        "pick": int(row["index"]),
        "pick_mean": float(row["mean"]),
        "pick_p95": float(row["p95"]),
        "pick_neighbourhood": smooth,
        "raw_best": int(raw[3]["index"]),
        "raw_mean": float(raw[3]["mean"]),
        "raw_p95": float(raw[3]["p95"]),
        "raw_neighbourhood": raw_smooth,
        "params": params,
    }
    print(
        f"{name:8} {len(rows):4} configs  pick #{row['index']}: {float(row['mean']):.2f} / "
        f"{float(row['p95']):.2f} (neighbourhood {smooth:.2f})   raw best #{raw[3]['index']}: "
        f"{float(raw[3]['mean']):.2f} / {float(raw[3]['p95']):.2f} (neighbourhood {raw_smooth:.2f})"
    )
json.dump(summary, open(f"{work}/tuning.json", "w"), indent=1)
PY
}

tables() {
    local tuned="$WORK/tuned.toml"
    : > "$tuned"
    for s in $TUNED; do
        [ "$s" = apf-med ] && continue
        if [ -f "docs/configs/tuned/$s.toml" ]; then
            cat "docs/configs/tuned/$s.toml" >> "$tuned"
        else
            echo "note: no docs/configs/tuned/$s.toml, $s runs with defaults in the tuned table" >&2
        fi
    done
    # Every scheme named with its bare tag: its defaults, written out in default.json.
    local defaults="$WORK/defaults.toml"
    : > "$defaults"
    for s in ${SCHEMES//,/ }; do
        printf '[schemes.%s]\nscheme = "%s"\n\n' "$s" "$s" >> "$defaults"
    done
    echo "== default parameters"
    "$WIPDR" eval --config "$defaults" --schemes "$SCHEMES" --data $FLOORS \
        --json "$WORK/default.json" | tail -n 16
    echo "== tuned parameters"
    "$WIPDR" eval --config "$tuned" --schemes "$SCHEMES" --data $FLOORS \
        --json "$WORK/tuned.json" | tail -n 16
    echo "== MED + APF, default and tuned"
    "$WIPDR" eval --config "$MED_BASE" --schemes wifi,apf --data $FLOORS \
        --json "$WORK/med-default.json" | tail -n 4
    local med_tuned="$MED_BASE"
    [ -f docs/configs/tuned/apf-med.toml ] && med_tuned=docs/configs/tuned/apf-med.toml
    "$WIPDR" eval --config "$med_tuned" --schemes wifi,apf --data $FLOORS \
        --json "$WORK/med-tuned.json" | tail -n 4
    echo "== the same configs on the synthetic fixture floor (not used for tuning)"
    "$WIPDR" eval --config "$defaults" --schemes "$SCHEMES" --data fixtures/sim/F1 \
        --json "$WORK/fixture-default.json" | tail -n 3
    "$WIPDR" eval --config "$tuned" --schemes "$SCHEMES" --data fixtures/sim/F1 \
        --json "$WORK/fixture-tuned.json" | tail -n 3
    python3 - "$WORK" "$SCHEMES" <<'PY'
# Formats the tables from the eval JSON files and writes them into docs/results/papers.md
# between the `<!-- papers.sh:begin -->` and `<!-- papers.sh:end -->` markers.
import json, os, re, sys, tomllib

work, order = sys.argv[1], sys.argv[2].split(",")
load = lambda f: json.load(open(f"{work}/{f}"))["pooled"]
default, tuned = load("default.json"), load("tuned.json")
med_default, med_tuned = load("med-default.json"), load("med-tuned.json")
n = default["wifi"]["count"] if "wifi" in default else 0


def fmt(s, keys):
    return " | ".join(f"{s[k]:.2f}" for k in keys)


def row(label, d, t, keys=("mean", "rms", "p95"), paper=""):
    cells = [label] + ([paper] if paper is not None else [])
    return "| " + " | ".join(cells) + f" | {fmt(d, keys)} | {fmt(t, keys)} |"


def head(first, keys=("mean", "rms", "p95"), paper="paper (their data)"):
    cols = [first] + ([paper] if paper else [])
    cols += [f"default {k}" for k in keys] + [f"tuned {k}" for k in keys]
    return "| " + " | ".join(cols) + " |\n|" + " --- |" * len(cols)


def scheme_row(label, s, paper):
    return row(label, default[s], tuned[s], paper=paper)


def flat(table, prefix=""):
    for k, v in table.items():
        if isinstance(v, dict):
            yield from flat(v, prefix + k + ".")
        elif k != "scheme":
            yield prefix + k, v


def show(v):
    return f"{v:.4g}" if isinstance(v, float) else str(v).lower()


def config_of(name):
    return json.load(open(f"{work}/{name}"))["config"].get("schemes", {})


default_cfg, tuned_cfg = config_of("default.json"), config_of("tuned.json")
med_tuned_cfg = config_of("med-tuned.json")


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
fx_default, fx_tuned = load("fixture-default.json"), load("fixture-tuned.json")
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
tuning_file = f"{work}/tuning.json"
if os.path.exists(tuning_file):
    tuning = json.load(open(tuning_file))
    out.append("\n### The sweeps (figures at tuning time, same protocol)\n")
    out.append("| sweep | configs | pick: mean / p95 | pick's neighbourhood | raw best: mean / p95 "
               "| raw best's neighbourhood |")
    out.append("| --- | --- | --- | --- | --- | --- |")
    for name, t in tuning.items():
        out.append(f"| `tune-{name}` | {t['configs']} | #{t['pick']}: {t['pick_mean']:.2f} / "
                   f"{t['pick_p95']:.2f} | {t['pick_neighbourhood']:.2f} | #{t['raw_best']}: "
                   f"{t['raw_mean']:.2f} / {t['raw_p95']:.2f} | {t['raw_neighbourhood']:.2f} |")
text = "\n".join(out) + "\n"
print(text)

doc = "docs/results/papers.md"
begin, end = "<!-- papers.sh:begin -->", "<!-- papers.sh:end -->"
if os.path.exists(doc):
    body = open(doc).read()
    if begin in body and end in body:
        pattern = re.compile(re.escape(begin) + ".*?" + re.escape(end), re.S)
        body = pattern.sub(lambda _: f"{begin}\n{text}{end}", body)
        open(doc, "w").write(body)
        print(f"rewrote the tables in {doc}")
    else:
        print(f"{doc} has no {begin} ... {end} markers: tables printed only", file=sys.stderr)
PY
}

case "$mode" in
    tune) tune ;;
    tables) tables ;;
    all) tune; tables ;;
    *) echo "usage: $0 [tables|tune|all]" >&2; exit 2 ;;
esac
