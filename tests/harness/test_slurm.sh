#!/usr/bin/env bash
# scripts/verify_slurm.sh through a real (single-node) Slurm: a 2-task job array and the dependent
# merge job, whose JSON summary and JUnit XML must equal an unsharded `crossdyn verify` of the same
# scenes (run times aside); then `verify_slurm.sh converge` (a sweep part) whose merged table and
# JSON must equal an unsharded `crossdyn converge` byte for byte. The cluster is started by scripts/slurm_localhost.sh on its own ports.
# Skipped (exit 77) where Slurm is not installed or the daemons cannot run (not root); CI installs
# Slurm (.ci/run), so there it runs.
#   usage: test_slurm.sh CROSSDYN SOURCE_DIR
set -uo pipefail
crossdyn=$1
src=$2
if ! command -v sbatch > /dev/null || [ ! -x /usr/sbin/slurmctld ] || [ ! -x /usr/sbin/slurmd ] ||
   [ "$(id -u)" -ne 0 ]; then
  echo "SKIP: Slurm (slurmctld, slurmd, sbatch) is not installed or this is not root"
  exit 77
fi
work=$(mktemp -d /tmp/crossdyn_slurm_test.XXXXXX)
cleanup() { "$src/scripts/slurm_localhost.sh" stop "$work/cluster" > /dev/null 2>&1; rm -rf "$work"; }
trap cleanup EXIT
eval "$("$src/scripts/slurm_localhost.sh" start "$work/cluster")" || { echo "FAIL: the cluster did not start"; exit 1; }
scenes=(torque_free_asymmetric spear1_case1 chain5 dual_spin)
cd "$work" || exit 1  # the jobs' .out files land here (scene names resolve to the source tree)
CROSSDYN=$crossdyn "$src/scripts/verify_slurm.sh" 2 "$work/out" "${scenes[@]}" || { echo "FAIL: submission"; exit 1; }
for _ in $(seq 1 240); do  # at most 120 s
  [ -z "$(squeue -h 2>/dev/null)" ] && break
  sleep 0.5
done
[ -z "$(squeue -h)" ] || { echo "FAIL: jobs still queued after 120 s"; squeue; exit 1; }
[ -s "$work/out/summary.json" ] && [ -s "$work/out/junit.xml" ] ||
  { echo "FAIL: the merge job wrote no summary"; cat crossdyn-*.out 2> /dev/null; exit 1; }
"$crossdyn" verify --quiet --json "$work/whole.json" --junit "$work/whole.xml" "${scenes[@]}" > /dev/null
/usr/bin/python3 - "$work" <<'PY' || exit 1
import json, re, sys
w = sys.argv[1]
def scrub(o):  # run times are each shard's own
    if isinstance(o, dict):
        return {k: scrub(v) for k, v in o.items() if k != "wall_seconds"}
    if isinstance(o, list):
        return [scrub(v) for v in o]
    return o
a, b = (scrub(json.load(open(w + p))) for p in ("/out/summary.json", "/whole.json"))
x, y = (re.sub(r'time="[^"]*"', 'time=""', open(w + p).read()) for p in ("/out/junit.xml", "/whole.xml"))
if a != b:
    sys.exit("FAIL: the merged JSON summary differs from verify's")
if x != y:
    sys.exit("FAIL: the merged JUnit XML differs from verify's")
print("PASS: Slurm array (2 tasks) + merge job = verify on %d scenes" % len(a.get("scenes", [])))
PY
# A sweep command through the same script: converge's models over 2 tasks.
CROSSDYN=$crossdyn "$src/scripts/verify_slurm.sh" converge 2 "$work/conv" pointing_flex ||
  { echo "FAIL: converge submission"; exit 1; }
for _ in $(seq 1 240); do
  [ -z "$(squeue -h 2>/dev/null)" ] && break
  sleep 0.5
done
[ -s "$work/conv/converge.json" ] || { echo "FAIL: the converge merge job wrote nothing"; cat crossdyn-*.out 2> /dev/null; exit 1; }
"$crossdyn" converge pointing_flex --quiet --json "$work/conv-whole.json" > "$work/conv-whole.txt"
cmp -s "$work/conv/converge.json" "$work/conv-whole.json" || { echo "FAIL: merged converge JSON differs"; exit 1; }
cmp -s "$work/conv/converge.txt" "$work/conv-whole.txt" || { echo "FAIL: merged converge table differs"; exit 1; }
echo "PASS: Slurm array (2 tasks) + merge job = converge pointing_flex"
