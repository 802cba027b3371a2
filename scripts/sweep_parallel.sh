#!/usr/bin/env bash
# Any sharded crossdyn sweep (verify, study, stability, converge) on one machine with GNU parallel (Debian
# package `parallel`): N shards at once, then `crossdyn merge` (README "Sharding a sweep").
#
#   scripts/sweep_parallel.sh COMMAND N OUTDIR [COMMAND's options and scenes ...] [--merge MERGE OPTIONS ...]
#
# runs `crossdyn COMMAND --quiet --shard K/N --part OUTDIR/part-K.json ...` for K = 0 .. N-1 and
# merges the parts. The merge writes, besides any MERGE OPTIONS (e.g. --report=OUTDIR/report):
#   verify:           OUTDIR/summary.json and OUTDIR/junit.xml
#   study, stability: OUTDIR/COMMAND.csv
#   converge:         OUTDIR/converge.json
# and prints the table the unsharded command prints. The same as the one-liner
#
#   seq 0 $((N-1)) | parallel crossdyn study -q SCENES... --shard {}/N --part out/part-{}.json; \
#     crossdyn merge out/part-*.json --csv out/study.csv
#
# A shard that ended with 1 (failed checks, a refused study scene) still wrote its part, so the
# merge always runs; its exit status is the whole run's. CROSSDYN names the program (default:
# crossdyn on PATH, else build/crossdyn of this source tree).
set -uo pipefail
if [ $# -lt 3 ]; then
  echo "usage: $0 verify|study|stability|converge N OUTDIR [options and scenes ...] [--merge merge options ...]" >&2
  exit 2
fi
command=$1
n=$2
out=$3
shift 3
case "$command" in
  verify | study | stability | converge) ;;
  *) echo "$0: '$command' is not sharded (verify, study, stability or converge)" >&2; exit 2 ;;
esac
args=()
merge_args=()
while [ $# -gt 0 ]; do
  if [ "$1" = --merge ]; then
    shift
    merge_args=("$@")
    break
  fi
  args+=("$1")
  shift
done
crossdyn=${CROSSDYN:-$(command -v crossdyn || echo "$(dirname "$0")/../build/crossdyn")}
command -v parallel >/dev/null || { echo "$0: GNU parallel is not installed (apt-get install parallel)" >&2; exit 2; }
mkdir -p "$out" || exit 2
rm -f "$out"/part-*.json  # parts of an earlier run must not be merged with these
# -q: the arguments reach crossdyn as given (no second shell parsing); --halt never: every shard
# runs even when another fails. The shards' own tables are not shown: the merge prints the whole.
seq 0 $((n - 1)) | parallel -q --halt never -j "$n" \
  "$crossdyn" "$command" --quiet --shard "{}/$n" --part "$out/part-{}.json" "${args[@]}" >/dev/null
case "$command" in
  verify) outputs=(--json "$out/summary.json" --junit "$out/junit.xml") ;;
  converge) outputs=(--json "$out/converge.json") ;;
  *) outputs=(--csv "$out/$command.csv") ;;
esac
"$crossdyn" merge "$out"/part-*.json "${outputs[@]}" "${merge_args[@]}"
