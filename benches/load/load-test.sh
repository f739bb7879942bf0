#!/usr/bin/env bash
# The load benchmark of `wipdr serve` (docs/results/serve.md): N phones replaying the real walks
# of ILC site1/F1 in real time (their IMU at its recorded rate, scans as recorded, 1 s
# batches), server and load generator on this machine, for each scheme and N. The phones
# start spread over RAMP_S seconds (default 30: a server meets phones arriving, not a
# thousand cold starts in one second) and each one replays walk after walk, a session each
# (`replay --loop`), so all N stream for the DURATION seconds after the ramp (default 60).
# Prints each run's request latency percentiles (while all N stream: the table's p50, p99, max;
# the whole run's p99: run_p99), samples sent/accepted and the server's memory a session,
# then a table. A repository command, not a test.
#
#   benches/load/load-test.sh                     # ekf and pmf, N = 100 250 500 1000 1500 2000
#   SCHEMES=pmf PHONES="1000 2000" DURATION=60 benches/load/load-test.sh
#   CONFIG=benches/load/pmf-point.toml SCHEMES="pmf-point pmf" benches/load/load-test.sh
#
# MODEL: a site model file to serve instead of fitting one; CONFIG: the config (TOML, paths
# from the repository's root) the model is fit with, e.g. for schemes of its own;
# SERVE_ARGS: more `wipdr serve` flags (e.g. SERVE_ARGS="--max-opens-per-s 30" RAMP_S=1).
# The column opens_retried counts session opens refused by that limit and retried.
#
# Needs ../shared/data (or WIPDR_DATA) and a release build (made here).
set -euo pipefail
cd "$(dirname "$0")/../.."
data="${WIPDR_DATA:-../shared/data}/ilc20/site1/F1"
target="${CARGO_TARGET_DIR:-target}"
cargo build --release --locked --bin wipdr
bin="$target/release/wipdr"
work="$(mktemp -d)"
server=""
cleanup() { [ -n "$server" ] && kill "$server" 2>/dev/null; rm -rf "$work"; }
trap cleanup EXIT
model="${MODEL:-$work/site1-F1.wipdr}"
[ -f "$model" ] || "$bin" fit --data "$data" --no-leave-one-out ${CONFIG:+--config "$CONFIG"} --out "$model"
od -An -tx1 -N32 /dev/urandom | tr -d ' \n' > "$work/tokens"
echo >> "$work/tokens"
walks=("$data"/path_data_files/*.txt.gz)
results="$work/results.tsv"
printf 'scheme\tphones\tp50_ms\tp99_ms\tmax_ms\trun_p99_ms\tsessions\topens_retried\tsent\taccepted\tkB_per_session\n' > "$results"
for scheme in ${SCHEMES:-ekf pmf}; do
  for n in ${PHONES:-100 250 500 1000 1500 2000}; do
    rm -f "$work/db.sqlite"*
    "$bin" serve --model "$model" --addr 127.0.0.1:0 --tokens "$work/tokens" --db "$work/db.sqlite" \
      --max-sessions-per-token 100000 ${SERVE_ARGS:-} 2> "$work/serve.log" &
    server=$!
    for _ in $(seq 600); do grep -q 'listening on' "$work/serve.log" && break; sleep 0.1; done
    url="$(sed -n 's/^wipdr serve: listening on //p' "$work/serve.log" | head -1)"
    rm -f "$work/run.json"
    ramp="${RAMP_S:-30}"
    echo "== $scheme, $n phones, a ${ramp} s ramp, then ${DURATION:-60} s"
    "$bin" replay --server "$url" --token-file "$work/tokens" --phones "$n" --concurrency "$n" \
      --speed 1 --batch-ms 1000 --ramp-s "$ramp" --loop \
      --duration-s "$(python3 -c "print($ramp + ${DURATION:-60})")" --scheme "$scheme" \
      --json "$work/run.json" "${walks[@]}" || true
    kill -TERM "$server"; wait "$server" || true; server=""
    [ -f "$work/run.json" ] || { printf '%s\t%s\tno result (see above)\n' "$scheme" "$n" >> "$results"; continue; }
    python3 - "$work/run.json" "$scheme" "$n" >> "$results" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
per = r.get("memory_bytes_per_session")
steady = r["steady_latency_ms"]
print("\t".join([sys.argv[2], sys.argv[3], "%.2f" % steady["p50"], "%.2f" % steady["p99"],
                 "%.2f" % steady["max"], "%.2f" % r["latency_ms"]["p99"], str(r["sessions"]), str(r["open_retries"]),
                 str(r["samples_sent"]), str(r["samples_accepted"]),
                 "-" if per is None else "%.0f" % (per / 1e3)]))
PY
  done
done
echo
column -t -s $'\t' "$results" 2>/dev/null || cat "$results"
