#!/usr/bin/env bash
#SBATCH --job-name=crossdyn-verify
#SBATCH --ntasks=1
#SBATCH --cpus-per-task=1
#SBATCH --time=01:00:00
#SBATCH --output=crossdyn-verify-%A_%a.out
# Sharded `crossdyn verify` on a Slurm cluster: a job array with one shard per task, and a merge
# job that starts when every task has succeeded (docs/sharding.md).
#
#   scripts/verify_slurm.sh [study|stability|converge] N OUTDIR [options and scenes ...]     (on a login node)
#
# shards `crossdyn verify`, or the command named first (`study`, `stability`: their merge writes
# OUTDIR/COMMAND.csv and OUTDIR/COMMAND.txt, the table, instead of summary.json and junit.xml;
# `converge`: OUTDIR/converge.json and OUTDIR/converge.txt).
#
# submits
#   sbatch --array=0-(N-1) verify_slurm.sh --role=task RUN    task K: crossdyn COMMAND --shard K/N --part RUN/part-K.json ...
#   sbatch --dependency=afterok:<array> verify_slurm.sh --role=merge RUN
#                                                              crossdyn merge RUN/part-*.json --json ... --junit ...
# and prints both job ids. RUN is a fresh folder OUTDIR/.crossdyn-run.XXXXXX made at submission;
# it holds the command, N, OUTDIR and the arguments (NUL-separated, so they reach crossdyn exactly
# as given: spaces, quotes, empty arguments), and the parts. The role of a job is the explicit
# --role argument the submission gives it, never guessed from Slurm's variables.
#
# Promises (as the program's): COMMAND, N (1 to 10000) and OUTDIR are checked before anything is
# submitted. A task that wrote its part ends successfully whatever its slice's verdict (failed
# checks, a refused study scene), so the merge runs and reports them; a task that wrote no part
# (bad input, an error, killed) fails, and the merge job then never starts (Slurm shows it as
# DependencyNeverSatisfied). Nothing in OUTDIR changes unless the merge succeeds (exit 0 or 1):
# only then are its outputs (written into RUN: the table too, never with the shell's `>` into
# OUTDIR) and the parts moved into OUTDIR, each file replaced by a rename; a refused merge leaves
# the earlier results as they were and the parts in RUN.
#
# OUTDIR must be on a file system every node sees, and the scenes too (merge checks their SHA-256
# against the files where it can find them); run it from the folder the scene paths are relative
# to. The #SBATCH lines above are defaults; override them on the command line through SBATCH_*
# variables (SBATCH_PARTITION, SBATCH_TIMELIMIT, ...) or edit them for your site.
#
# Checked on a real single-node Slurm (Debian's Slurm 22.05, started by scripts/slurm_localhost.sh):
# tests/harness/test_slurm.sh submits a 2-task array and the merge job and compares the merged
# summary and JUnit with an unsharded verify (CI installs Slurm for it); the roles, the checks and
# the publishing are also tested without Slurm (tests/harness/test_sweep_scripts.sh, a stand-in
# sbatch). Not yet run on a multi-node cluster. CROSSDYN names the program (default: crossdyn on
# PATH, else build/crossdyn of this source tree, resolved at submission).
set -uo pipefail

# Reads RUN/meta: command, N, OUTDIR, CROSSDYN, then the arguments (NUL-separated).
read_run() {
  run=$1
  [ -f "$run/meta" ] || { echo "$0: '$run' is not a run folder made by this script (no meta)" >&2; exit 2; }
  local fields=()
  mapfile -d '' fields < "$run/meta"
  [ "${#fields[@]}" -ge 4 ] || { echo "$0: '$run/meta' is incomplete" >&2; exit 2; }
  command=${fields[0]}
  n=${fields[1]}
  out=${fields[2]}
  crossdyn=${fields[3]}
  args=("${fields[@]:4}")
}

case "${1:-}" in
  --role=task)
    [ $# -eq 2 ] || { echo "$0: --role=task RUN" >&2; exit 2; }
    read_run "$2"
    k=${SLURM_ARRAY_TASK_ID:-}
    if ! [[ "$k" =~ ^[0-9]+$ ]] || [ "$k" -ge "$n" ]; then
      echo "$0: --role=task runs in a job array task (SLURM_ARRAY_TASK_ID from 0 to $((n - 1)), not '$k')" >&2
      exit 2
    fi
    "$crossdyn" "$command" --quiet --shard "$k/$n" --part "$run/part-$k.json" "${args[@]}"
    rc=$?
    # The part is written (atomically) or not at all: written, the merge gives the verdict.
    [ -f "$run/part-$k.json" ] && exit 0
    [ "$rc" -eq 0 ] && rc=3
    exit "$rc"
    ;;
  --role=merge)
    [ $# -eq 2 ] || { echo "$0: --role=merge RUN" >&2; exit 2; }
    read_run "$2"
    parts=()
    for ((k = 0; k < n; ++k)); do parts+=("$run/part-$k.json"); done
    case "$command" in
      verify)
        names=(summary.json junit.xml)
        "$crossdyn" merge "${parts[@]}" --json "$run/summary.json" --junit "$run/junit.xml"
        ;;
      converge)
        names=(converge.json converge.txt)
        "$crossdyn" merge "${parts[@]}" --json "$run/converge.json" > "$run/converge.txt"
        ;;
      *)
        names=("$command.csv" "$command.txt")
        "$crossdyn" merge "${parts[@]}" --csv "$run/$command.csv" > "$run/$command.txt"
        ;;
    esac
    rc=$?
    if [ "$rc" -ne 0 ] && [ "$rc" -ne 1 ]; then
      rm -f -- "$run/converge.txt" "$run/$command.txt"
      echo "$0: the merge ended with exit status $rc; '$out' is as it was; the parts are in '$run'" >&2
      exit "$rc"
    fi
    for old in "$out"/part-*.json; do  # parts of an earlier run with more shards
      [ -e "$old" ] || continue
      k=${old##*/part-}
      k=${k%.json}
      [[ "$k" =~ ^[0-9]+$ ]] && [ "$k" -ge "$n" ] && rm -f -- "$old"
    done
    for ((k = 0; k < n; ++k)); do mv -f -- "$run/part-$k.json" "$out/part-$k.json" || exit 3; done
    for name in "${names[@]}"; do
      [ -e "$run/$name" ] && { mv -f -- "$run/$name" "$out/$name" || exit 3; }
    done
    rm -rf -- "$run"
    exit "$rc"
    ;;
  --role=*)
    echo "$0: unknown role '${1#--role=}' (task or merge; the submission gives it)" >&2
    exit 2
    ;;
esac

# Submission (login node): check everything, then the array and the merge depending on it.
command=verify
case "${1:-}" in
  verify | study | stability | converge) command=$1; shift ;;
esac
if [ $# -lt 2 ]; then
  echo "usage: $0 [verify|study|stability|converge] N OUTDIR [options and scenes ...]" >&2
  exit 2
fi
n=$1
out=$2
shift 2
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
here=$(cd "$(dirname "$0")" && pwd)
crossdyn=${CROSSDYN:-$(command -v crossdyn || echo "$here/../build/crossdyn")}
if [ ! -x "$crossdyn" ] || [ -d "$crossdyn" ]; then
  echo "$0: '$crossdyn' is not a program (set CROSSDYN to crossdyn's path)" >&2
  exit 2
fi
crossdyn=$(cd "$(dirname "$crossdyn")" && pwd)/$(basename "$crossdyn")
command -v sbatch > /dev/null || { echo "$0: sbatch is not installed (this submits to Slurm)" >&2; exit 2; }
mkdir -p -- "$out" || exit 2
out=$(cd "$out" && pwd)
run=$(mktemp -d "$out/.crossdyn-run.XXXXXX") || { echo "$0: cannot make a folder in '$out'" >&2; exit 3; }
printf '%s\0' "$command" "$n" "$out" "$crossdyn" "$@" > "$run/meta" || exit 3
array=$(sbatch --parsable --export=ALL --array=0-$((n - 1)) "$here/verify_slurm.sh" --role=task "$run") ||
  { rm -rf -- "$run"; exit 2; }
array=${array%%;*}  # --parsable prints "jobid" or "jobid;cluster"
merge=$(sbatch --parsable --export=ALL --job-name=crossdyn-merge --output=crossdyn-merge-%j.out \
        --dependency=afterok:"$array" "$here/verify_slurm.sh" --role=merge "$run") || exit 2
echo "shards: job array ${array} (tasks 0-$((n - 1))); merge: job ${merge%%;*} (after all shards succeed)"
echo "run folder: $run"
if [ "$command" = verify ]; then
  echo "results: $out/summary.json, $out/junit.xml"
elif [ "$command" = converge ]; then
  echo "results: $out/converge.txt, $out/converge.json"
else
  echo "results: $out/$command.txt, $out/$command.csv"
fi
