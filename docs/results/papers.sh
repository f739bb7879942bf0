#!/usr/bin/env bash
# Regenerates the papers' tables on the real walks (docs/results/papers.md).
#
#   docs/results/papers.sh tables   # evaluate default and tuned configs, rewrite the tables
#                                   # (= python3 docs/results/regenerate.py --only papers.md)
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

# The tables are a recipe of docs/results/regenerate.py (docs/results/recipes/comp_papers.py):
# the same default and tuned evaluations, rewritten between the markers of papers.md.
tables() {
    WIPDR="$WIPDR" PAPERS_SCHEMES="$SCHEMES" python3 docs/results/regenerate.py --only papers.md
}

case "$mode" in
    tune) tune ;;
    tables) tables ;;
    all) tune; tables ;;
    *) echo "usage: $0 [tables|tune|all]" >&2; exit 2 ;;
esac
