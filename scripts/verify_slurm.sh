#!/usr/bin/env bash
#SBATCH --job-name=crossdyn-verify
#SBATCH --ntasks=1
#SBATCH --cpus-per-task=1
#SBATCH --time=01:00:00
#SBATCH --output=crossdyn-verify-%A_%a.out
# Sharded `crossdyn verify` on a Slurm cluster: a job array with one shard per task, and a merge
# job that starts when every task has succeeded (README "Sharding a sweep").
#
#   scripts/verify_slurm.sh [study|stability|converge] N OUTDIR [options and scenes ...]     (on a login node)
#
# shards `crossdyn verify`, or the command named first (`study`, `stability`: their merge writes
# OUTDIR/COMMAND.csv and OUTDIR/COMMAND.txt, the table, instead of summary.json and junit.xml;
# `converge`: OUTDIR/converge.json and OUTDIR/converge.txt).
#
# submits
#   sbatch --array=0-(N-1) scripts/verify_slurm.sh ...   task K: crossdyn verify --shard K/N --part OUTDIR/part-K.json
#   sbatch --dependency=afterok:<array job id> ...       crossdyn merge OUTDIR/part-*.json --json OUTDIR/summary.json --junit OUTDIR/junit.xml
# and prints both job ids. OUTDIR must be on a file system every node sees, and the scenes too
# (merge checks their SHA-256 against the files where it can find them); run it from the folder
# the scene paths are relative to. A task whose slice has failed checks (exit status 1) ends
# successfully so that the merge runs and reports them; a task that could not run (2, 3, killed)
# fails, and the merge job then never starts (Slurm shows it as DependencyNeverSatisfied).
# The #SBATCH lines above are defaults; override them on the command line through SBATCH_*
# variables (SBATCH_PARTITION, SBATCH_TIMELIMIT, ...) or edit them for your site.
#
# Checked on a real single-node Slurm (Debian's Slurm 22.05, started by scripts/slurm_localhost.sh):
# tests/harness/test_slurm.sh submits a 2-task array and the merge job and compares the merged
# summary and JUnit with an unsharded verify (CI installs Slurm for it). Not yet run on a
# multi-node cluster. CROSSDYN names the program (default: crossdyn on PATH, else build/crossdyn
# of this source tree, resolved at submission).
set -uo pipefail
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

# The role comes from Slurm's variables: an array task runs a shard, another job the merge, and
# outside Slurm the script submits both. (In a job, Slurm runs a copy of this script, so the
# program is found through CROSSDYN, PATH or the submission folder's build/crossdyn.)
if [ -n "${SLURM_ARRAY_TASK_ID:-}" ]; then
  crossdyn=${CROSSDYN:-$(command -v crossdyn || echo "${SLURM_SUBMIT_DIR:-.}/build/crossdyn")}
  k=$SLURM_ARRAY_TASK_ID
  "$crossdyn" "$command" --quiet --shard "$k/$n" --part "$out/part-$k.json" "$@"
  rc=$?
  [ "$rc" -eq 1 ] && exit 0  # failed checks (a refused study scene): the part is written, merge reports them
  exit "$rc"
elif [ -n "${SLURM_JOB_ID:-}" ]; then
  crossdyn=${CROSSDYN:-$(command -v crossdyn || echo "${SLURM_SUBMIT_DIR:-.}/build/crossdyn")}
  if [ "$command" = verify ]; then
    "$crossdyn" merge "$out"/part-*.json --json "$out/summary.json" --junit "$out/junit.xml"
  elif [ "$command" = converge ]; then
    "$crossdyn" merge "$out"/part-*.json --json "$out/converge.json" > "$out/converge.txt"
  else
    "$crossdyn" merge "$out"/part-*.json --csv "$out/$command.csv" > "$out/$command.txt"
  fi
else
  # Submission (login node): the array, then the merge depending on it.
  here=$(cd "$(dirname "$0")" && pwd)
  export CROSSDYN=${CROSSDYN:-$(command -v crossdyn || echo "$here/../build/crossdyn")}
  mkdir -p "$out" || exit 2
  rm -f "$out"/part-*.json  # parts of an earlier run must not be merged with these
  array=$(sbatch --parsable --export=ALL --array=0-$((n - 1)) "$here/verify_slurm.sh" "$command" "$n" "$out" "$@") ||
    exit 2
  array=${array%%;*}  # --parsable prints "jobid" or "jobid;cluster"
  merge=$(sbatch --parsable --export=ALL --job-name=crossdyn-merge --output=crossdyn-merge-%j.out \
          --dependency=afterok:"$array" "$here/verify_slurm.sh" "$command" "$n" "$out" "$@") || exit 2
  echo "shards: job array ${array} (tasks 0-$((n - 1))); merge: job ${merge%%;*} (after all shards succeed)"
  if [ "$command" = verify ]; then
    echo "results: $out/summary.json, $out/junit.xml"
  elif [ "$command" = converge ]; then
    echo "results: $out/converge.txt, $out/converge.json"
  else
    echo "results: $out/$command.txt, $out/$command.csv"
  fi
fi
