#!/usr/bin/env bash
# The IPIN logfiles under leave-one-WALK-out instead of issue 15's leave-one-route-out: each
# walk becomes its own route (TrialNN_repetitionMM -> TrialNNMM_repetition01, links in a
# temporary folder, the data read in place), so the radio map of a test walk holds the other
# repetitions of its own route. A diagnostic of what the map's coverage is worth, not the
# protocol: the same route's other walks are in the map (docs/results/accuracy.md,
# "IPIN: the EvAAL bar is met when the map covers the route").
#
#   bash docs/results/ipin_walk_folds.sh [DATA_DIR] [-- extra `wipdr eval` arguments]
#
# DATA_DIR defaults to $WIPDR_DATA/ipin2023 ($WIPDR_DATA defaulting to ../shared/data).
# WIPDR_BIN picks the binary (default target/release/wipdr).
set -euo pipefail
data="${1:-${WIPDR_DATA:-../shared/data}/ipin2023}"
[ "$#" -gt 0 ] && shift
[ "${1:-}" = "--" ] && shift
bin="${WIPDR_BIN:-target/release/wipdr}"
data="$(cd "$data" && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/trials"
for f in "$data"/*.csv; do ln -s "$f" "$tmp/"; done
for f in "$data"/trials/*; do
  name="$(basename "$f" | sed -E 's/Trial([0-9]+)_repetition([0-9]+)/Trial\1\2_repetition01/')"
  ln -s "$f" "$tmp/trials/$name"
done
"$bin" eval --data "$tmp" "$@"
