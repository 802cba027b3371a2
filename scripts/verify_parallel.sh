#!/usr/bin/env bash
# Sharded `crossdyn verify` on one machine with GNU parallel (Debian package `parallel`): N shards
# at once, then `crossdyn merge` (README "Sharding a sweep").
#
#   scripts/verify_parallel.sh N OUTDIR [verify options and scenes ...]
#
# writes OUTDIR/part-K.json (K = 0 .. N-1), OUTDIR/summary.json and OUTDIR/junit.xml (add
# `--report` to the merge line below for the HTML report). The same as the one-liner
#
#   seq 0 $((N-1)) | parallel crossdyn verify -q --shard {}/N --part out/part-{}.json && \
#     crossdyn merge out/part-*.json --json out/summary.json --junit out/junit.xml
#
# except that a shard whose checks failed (exit status 1) still lets the merge run: the merge's
# exit status is the verdict of the whole run (0 pass, 1 a check failed, 2 bad input or parts
# that do not belong together, 3 an error). CROSSDYN names the program (default: crossdyn on
# PATH, else build/crossdyn of this source tree).
set -uo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 N OUTDIR [verify options and scenes ...]" >&2
  exit 2
fi
n=$1
out=$2
shift 2
crossdyn=${CROSSDYN:-$(command -v crossdyn || echo "$(dirname "$0")/../build/crossdyn")}
command -v parallel >/dev/null || { echo "$0: GNU parallel is not installed (apt-get install parallel)" >&2; exit 2; }
mkdir -p "$out" || exit 2
rm -f "$out"/part-*.json  # parts of an earlier run must not be merged with these
# -q: the verify arguments reach crossdyn as given (no second shell parsing); --halt never: every
# shard runs even when another fails. Exit status 1 (failed checks) is the slice's verdict.
seq 0 $((n - 1)) | parallel -q --halt never -j "$n" \
  "$crossdyn" verify --quiet --shard "{}/$n" --part "$out/part-{}.json" "$@"
"$crossdyn" merge "$out"/part-*.json --json "$out/summary.json" --junit "$out/junit.xml"
