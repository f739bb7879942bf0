#!/usr/bin/env bash
# Instructions a sample of the Positioner, counted by callgrind (repeatable whatever the
# machine's load, unlike timings): the bench's walk (ILC site1/F1, the longest walk) positioned
# by `wipdr locate --model` with the model of its protocol fold, counting only inside
# `Positioner::push`. Writes callgrind files into the output folder for
# `callgrind_annotate FILE`.
#
#   bash benches/profile_positioner.sh [OUT_DIR] [SCHEME...]     (default: target/profile, ekf pmf)
#
# Needs valgrind and the real data (../shared/data, or $WIPDR_DATA).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/profile}"
shift || true
schemes=("$@")
[ ${#schemes[@]} -gt 0 ] || schemes=(ekf pmf)
data="${WIPDR_DATA:-../shared/data}"
floor="$data/ilc20/site1/F1"
walk_id=5dd9ef979191710006b57086
walk="$floor/path_data_files/$walk_id.txt.gz"
[ -f "$walk" ] || { echo "no $walk: the profile needs the real data" >&2; exit 2; }
command -v valgrind >/dev/null || { echo "valgrind not found" >&2; exit 2; }
mkdir -p "$out"
cargo build --release --locked --bin wipdr
bin=target/release/wipdr
[ -f "$out/model.wipdr" ] || "$bin" fit --data "$floor" --leave-out-fold-of "$walk_id" --no-leave-one-out --out "$out/model.wipdr"
# Samples as the Positioner takes them: every sensor row, and each Wi-Fi scan once (the
# plain stream has a row per AP heard).
"$bin" export-stream "$walk" --out "$out/stream.csv" 2>/dev/null
samples=$(awk -F, '$1 !~ /^(#|t_ms)/ { if ($2 == "wifi") scans[$1] = 1; else n++ }
    END { for (t in scans) n++; print n }' "$out/stream.csv")
for s in "${schemes[@]}"; do
    # --error-exitcode does not cover the program's own exit code; the log's last lines do.
    if ! valgrind --tool=callgrind --callgrind-out-file="$out/callgrind.$s.out" \
        --toggle-collect='wipdr_positioning::positioner::Positioner::push' \
        "$bin" --no-cache locate --model "$out/model.wipdr" "$walk" --scheme "$s" \
        --out "$out/track.$s.csv" 2>"$out/valgrind.$s.log" >/dev/null ||
        grep -q '^error:' "$out/valgrind.$s.log"; then
        grep -v '^==' "$out/valgrind.$s.log" >&2
        echo "$s: wipdr locate failed under valgrind (an old model.wipdr in $out? delete it)" >&2
        exit 1
    fi
    total=$(grep -o 'I *refs: *[0-9,]*' "$out/valgrind.$s.log" | tr -dc '0-9')
    echo "$s: $total instructions in Positioner::push, $samples samples: $((total / samples)) a sample"
done
