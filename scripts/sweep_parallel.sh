#!/usr/bin/env bash
# Any sharded crossdyn sweep (verify, study, stability, converge) on one machine: N shards as
# background jobs, then `crossdyn merge` (docs/sharding.md).
#
#   scripts/sweep_parallel.sh COMMAND N OUTDIR [COMMAND's options and scenes ...] [--merge MERGE OPTIONS ...]
#
# runs `crossdyn COMMAND --quiet --shard K/N --part PART-K ...` for K = 0 .. N-1 (at most
# CROSSDYN_JOBS at once, default: the number of processors) and merges the parts. The merge
# writes, besides any MERGE OPTIONS (e.g. --report=OUTDIR/report):
#   verify:           OUTDIR/summary.json and OUTDIR/junit.xml
#   study, stability: OUTDIR/COMMAND.csv
#   converge:         OUTDIR/converge.json
# and OUTDIR/part-K.json, and prints the table the unsharded command prints.
#
# The promises of the program hold for the script too:
# - Arguments reach crossdyn exactly as given (spaces, quotes, empty arguments, '{}'): they are
#   never parsed by a second shell or by GNU parallel.
# - COMMAND, N (1 to 10000), OUTDIR and CROSSDYN_JOBS are checked before anything starts; the
#   program checks its own options before any work, so a bad option is exit status 2.
# - Nothing in OUTDIR changes unless the merge succeeds (exit 0 or 1): the shards write into a
#   fresh folder OUTDIR/.crossdyn-run.XXXXXX, and only a finished merge's outputs and parts are
#   moved into OUTDIR (each file replaced by a rename). A refused merge (2), an error (3) or
#   Ctrl-C (130) leaves the earlier results as they were; the new parts stay in the run folder
#   (named on stderr) to merge by hand, or are removed when there are none.
# - A shard that wrote its part (whatever its own verdict: failed checks, a refused study scene)
#   lets the merge run, whose exit status is the whole run's. A shard that wrote no part ends the
#   run with that shard's exit status.
# CROSSDYN names the program (default: crossdyn on PATH, else build/crossdyn of this source tree).
set -uo pipefail
usage() {
  echo "usage: $0 verify|study|stability|converge N OUTDIR [options and scenes ...] [--merge merge options ...]" >&2
  exit 2
}
[ $# -ge 3 ] || usage
command=$1
n=$2
out=$3
shift 3
case "$command" in
  verify | study | stability | converge) ;;
  *) echo "$0: '$command' is not sharded (verify, study, stability or converge)" >&2; exit 2 ;;
esac
if ! [[ "$n" =~ ^[1-9][0-9]{0,4}$ ]] || [ "$n" -gt 10000 ]; then
  echo "$0: N must be a whole number from 1 to 10000, not '$n'" >&2
  exit 2
fi
if [ -z "$out" ]; then
  echo "$0: OUTDIR is empty" >&2
  exit 2
fi
if [ -e "$out" ] && [ ! -d "$out" ]; then
  echo "$0: OUTDIR '$out' exists and is not a folder" >&2
  exit 2
fi
jobs_max=${CROSSDYN_JOBS:-$(nproc 2> /dev/null || echo 1)}
if ! [[ "$jobs_max" =~ ^[1-9][0-9]{0,4}$ ]]; then
  echo "$0: CROSSDYN_JOBS must be a whole number from 1, not '$jobs_max'" >&2
  exit 2
fi
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
if [ ! -x "$crossdyn" ] || [ -d "$crossdyn" ]; then
  echo "$0: '$crossdyn' is not a program (set CROSSDYN to crossdyn's path)" >&2
  exit 2
fi

mkdir -p -- "$out" || exit 2
stage=$(mktemp -d "$out/.crossdyn-run.XXXXXX") || { echo "$0: cannot make a folder in '$out'" >&2; exit 3; }
pids=()
interrupted() {
  trap - INT TERM
  for p in "${pids[@]}"; do kill -TERM "$p" 2> /dev/null; done
  wait
  rm -rf -- "$stage"
  echo "$0: interrupted; OUTDIR is as it was" >&2
  exit 130
}
trap interrupted INT TERM

# The shards: each in the background, its exit status in the run folder.
for ((k = 0; k < n; ++k)); do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs_max" ]; do wait -n; done
  (
    "$crossdyn" "$command" --quiet --shard "$k/$n" --part "$stage/part-$k.json" "${args[@]}" > /dev/null
    echo $? > "$stage/rc-$k"
  ) &
  pids+=($!)
done
wait

worst=0
missing=0
for ((k = 0; k < n; ++k)); do
  [ -f "$stage/part-$k.json" ] && continue
  rc=$(cat "$stage/rc-$k" 2> /dev/null || echo 3)
  [ "$rc" -eq 0 ] && rc=3  # ended well but wrote no part: an error
  echo "$0: shard $k/$n wrote no part (exit status $rc)" >&2
  missing=$((missing + 1))
  [ "$rc" -gt "$worst" ] && worst=$rc
done
if [ "$missing" -gt 0 ]; then
  rm -rf -- "$stage"
  echo "$0: nothing merged; OUTDIR is as it was" >&2
  exit "$worst"
fi

case "$command" in
  verify) names=(summary.json junit.xml); outputs=(--json "$stage/summary.json" --junit "$stage/junit.xml") ;;
  converge) names=(converge.json); outputs=(--json "$stage/converge.json") ;;
  *) names=("$command.csv"); outputs=(--csv "$stage/$command.csv") ;;
esac
parts=()
for ((k = 0; k < n; ++k)); do parts+=("$stage/part-$k.json"); done
"$crossdyn" merge "${parts[@]}" "${outputs[@]}" "${merge_args[@]}"
rc=$?
if [ "$rc" -ne 0 ] && [ "$rc" -ne 1 ]; then
  echo "$0: the merge ended with exit status $rc; OUTDIR is as it was; the parts are in '$stage'" >&2
  exit "$rc"
fi
# Publish: the parts of this run replace the earlier ones, then the merged outputs.
trap '' INT TERM
for old in "$out"/part-*.json; do
  [ -e "$old" ] || continue
  k=${old##*/part-}
  k=${k%.json}
  [[ "$k" =~ ^[0-9]+$ ]] && [ "$k" -ge "$n" ] && rm -f -- "$old"
done
for ((k = 0; k < n; ++k)); do mv -f -- "$stage/part-$k.json" "$out/part-$k.json" || exit 3; done
for name in "${names[@]}"; do
  [ -e "$stage/$name" ] && { mv -f -- "$stage/$name" "$out/$name" || exit 3; }
done
rm -rf -- "$stage"
exit "$rc"
