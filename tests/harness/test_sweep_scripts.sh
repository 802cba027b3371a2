#!/usr/bin/env bash
# Class 9 of issue 23: the sweep scripts keep the same promises as the program.
# scripts/sweep_parallel.sh, scripts/verify_parallel.sh and scripts/verify_slurm.sh (through a
# stand-in sbatch that runs the array tasks and the dependent merge job at once, honouring
# afterok) against a stand-in crossdyn that records its arguments and does what the test says:
#   - arguments pass through unchanged (spaces, quotes, empty arguments, '{}', '$(...)', '*');
#   - N, COMMAND and OUTDIR are checked before anything starts (nothing run, nothing made);
#   - a shard that wrote its part (exit 1: failed checks; 3: a scene's error) lets the merge run;
#     a shard that wrote none stops the run with its status, OUTDIR untouched;
#   - a refused merge (2) or an error (3) leaves the earlier outputs and parts as they were (no
#     0-byte table), a merge that ends 0 or 1 replaces them;
#   - verify_slurm.sh's role is the explicit --role argument: Slurm's variables in the environment
#     of a submission do not make it a task; --role=task outside an array task is refused.
# Then one real run: sweep_parallel.sh verify with the real crossdyn on two scenes.
#   usage: test_sweep_scripts.sh CROSSDYN SOURCE_DIR
set -uo pipefail
real=$1
src=$2
work=$(mktemp -d /tmp/crossdyn_sweep_scripts.XXXXXX)
trap 'rm -rf "$work"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
pass() { echo "ok: $*"; }

# The stand-in crossdyn. Every call appends its arguments (NUL-separated, then a record separator
# line) to $STUB_LOG. Shards write their part unless STUB_NO_PART is set, and exit STUB_SHARD_RC;
# merge writes its --json/--junit/--csv files and a table when STUB_MERGE_RC is 0 or 1.
mkdir -p "$work/bin"
cat > "$work/bin/crossdyn" <<'STUB'
#!/usr/bin/env bash
{ printf '%s\0' "$@"; printf '\n--call--\n'; } >> "$STUB_LOG"
if [ "$1" = merge ]; then
  rc=${STUB_MERGE_RC:-0}
  if [ "$rc" -le 1 ]; then
    while [ $# -gt 0 ]; do
      case "$1" in --json | --junit | --csv) echo "new $1" > "$2"; shift ;; esac
      shift
    done
    echo "new table"
  else
    echo "crossdyn: error: merge refused (stand-in)" >&2
  fi
  exit "$rc"
fi
part=
while [ $# -gt 0 ]; do
  [ "$1" = --part ] && part=$2
  shift
done
[ -z "${STUB_NO_PART:-}" ] && [ -n "$part" ] && echo '{}' > "$part"
exit "${STUB_SHARD_RC:-0}"
STUB
chmod +x "$work/bin/crossdyn"
stub=$work/bin/crossdyn

# The stand-in sbatch: --array=0-M runs the script once per task with SLURM_ARRAY_TASK_ID (and
# remembers whether every task succeeded under a job id); --dependency=afterok:ID runs the script
# only when job ID succeeded. Prints the job id (--parsable).
mkdir -p "$work/slurm"
cat > "$work/bin/sbatch" <<'SB'
#!/usr/bin/env bash
array= dep=
while [ $# -gt 0 ]; do
  case "$1" in
    --array=*) array=${1#--array=} ;;
    --dependency=afterok:*) dep=${1#--dependency=afterok:} ;;
    --*) ;;
    *) break ;;
  esac
  shift
done
id=$(( $(ls "$SBATCH_STATE" | wc -l) + 100 ))
script=$1
shift
ok=1
if [ -n "$array" ]; then
  for ((k = ${array%-*}; k <= ${array#*-}; ++k)); do
    SLURM_JOB_ID=$id SLURM_ARRAY_TASK_ID=$k bash "$script" "$@" > /dev/null 2>> "$SBATCH_STATE/../stderr" || ok=0
  done
elif [ -n "$dep" ]; then
  if [ "$(cat "$SBATCH_STATE/$dep")" = 1 ]; then
    SLURM_JOB_ID=$id bash "$script" "$@" > "$SBATCH_STATE/../merge.out" 2>> "$SBATCH_STATE/../stderr" || ok=0
  else
    ok=never
  fi
fi
echo "$ok" > "$SBATCH_STATE/$id"
echo "$id"
SB
chmod +x "$work/bin/sbatch"
export SBATCH_STATE=$work/slurm/state
mkdir -p "$SBATCH_STATE"

export STUB_LOG=$work/log
calls() { grep -c -- '--call--' "$STUB_LOG" 2> /dev/null || echo 0; }
reset() { rm -f "$STUB_LOG" "$work/slurm/stderr" "$work/slurm/merge.out"; rm -rf "$work/out"; unset STUB_NO_PART STUB_SHARD_RC STUB_MERGE_RC; }
# The arguments of the shard calls after "--part FILE", one line each as %q words.
shard_args() {
  python3 - "$STUB_LOG" <<'PY'
import sys
data = open(sys.argv[1], 'rb').read().split(b'\n--call--\n')
for call in data:
    if not call:
        continue
    a = call.split(b'\0')[:-1]
    if a and a[0] == b'merge':
        continue
    i = a.index(b'--part')
    print(repr(a[i + 2:]))
PY
}
weird=("a b" "" "{}" "x'y\"z" '$(touch pwned)' '*' "--opt=1 2" "tab	here")
expected=$(python3 -c 'import sys; print(repr([a.encode() for a in sys.argv[1:]]))' "${weird[@]}")

for runner in sweep_parallel verify_parallel verify_slurm; do
  run() {  # run N OUTDIR args...
    case $runner in
      sweep_parallel) CROSSDYN=$stub "$src/scripts/sweep_parallel.sh" verify "$@" ;;
      verify_parallel) CROSSDYN=$stub "$src/scripts/verify_parallel.sh" "$@" ;;
      verify_slurm) PATH=$work/bin:$PATH CROSSDYN=$stub "$src/scripts/verify_slurm.sh" "$@" ;;
    esac
  }
  cd "$work" || exit 1

  # Arguments pass through unchanged, to every shard.
  reset
  run 3 "$work/out" "${weird[@]}" > /dev/null 2>&1
  got=$(shard_args | sort -u)
  if [ "$(shard_args | wc -l)" -eq 3 ] && [ "$got" = "$expected" ] && [ ! -e "$work/pwned" ]; then
    pass "$runner: arguments reach every shard unchanged"
  else
    fail "$runner: arguments changed: $got (expected $expected)"
  fi

  # N and OUTDIR are checked before anything starts.
  for bad in 0 -1 1e3 10001 '' 'a[$(touch pwned)]' '2 ' 0x2; do
    reset
    run "$bad" "$work/out" scene.yaml > /dev/null 2>&1
    rc=$?
    if [ "$rc" -eq 2 ] && [ "$(calls)" -eq 0 ] && [ ! -e "$work/out" ] && [ ! -e "$work/pwned" ]; then
      pass "$runner: N '$bad' refused before anything starts"
    else
      fail "$runner: N '$bad': exit $rc, $(calls) crossdyn calls, out $(ls -d "$work/out" 2> /dev/null)"
    fi
  done
  reset
  touch "$work/afile"
  run 2 "$work/afile" scene.yaml > /dev/null 2>&1
  rc=$?
  [ "$rc" -eq 2 ] && [ "$(calls)" -eq 0 ] && pass "$runner: OUTDIR naming a file refused first" ||
    fail "$runner: OUTDIR naming a file: exit $rc, $(calls) calls"
  run 2 "" scene.yaml > /dev/null 2>&1
  rc=$?
  [ "$rc" -eq 2 ] && [ "$(calls)" -eq 0 ] && pass "$runner: empty OUTDIR refused first" ||
    fail "$runner: empty OUTDIR: exit $rc, $(calls) calls"

  # A shard that wrote its part lets the merge run, whatever its own exit status.
  for shard_rc in 1 3; do
    reset
    STUB_SHARD_RC=$shard_rc run 2 "$work/out" scene.yaml > /dev/null 2>&1
    rc=$?
    if [ "$rc" -eq 0 ] && grep -q "new --json" "$work/out/summary.json" 2> /dev/null; then
      pass "$runner: shards ending $shard_rc with their parts written are merged"
    else
      fail "$runner: shards ending $shard_rc with parts: exit $rc, summary $(cat "$work/out/summary.json" 2> /dev/null)"
    fi
  done

  # Earlier results; then runs that fail keep them exactly.
  seed() {
    rm -rf "$work/out"
    mkdir -p "$work/out"
    echo "old summary" > "$work/out/summary.json"
    echo "old junit" > "$work/out/junit.xml"
    echo "old part" > "$work/out/part-0.json"
  }
  same_old() {
    [ "$(cat "$work/out/summary.json")" = "old summary" ] && [ "$(cat "$work/out/junit.xml")" = "old junit" ] &&
      [ "$(cat "$work/out/part-0.json")" = "old part" ]
  }
  for merge_rc in 2 3; do
    reset
    seed
    STUB_MERGE_RC=$merge_rc run 2 "$work/out" scene.yaml > /dev/null 2>&1
    rc=$?
    if [ "$rc" -eq "$merge_rc" ] && same_old; then
      pass "$runner: a merge ending $merge_rc leaves the earlier outputs and parts"
    elif [ "$runner" = verify_slurm ] && [ "$rc" -eq 0 ] && same_old; then
      pass "$runner: a merge job ending $merge_rc leaves the earlier outputs and parts"
    else
      fail "$runner: merge $merge_rc: exit $rc, summary '$(cat "$work/out/summary.json" 2> /dev/null)'"
    fi
  done
  reset
  seed
  STUB_NO_PART=1 STUB_SHARD_RC=2 run 2 "$work/out" scene.yaml > /dev/null 2>&1
  rc=$?
  merges=$(grep -c -a '^merge' "$STUB_LOG" 2> /dev/null || true)
  if same_old && [ "${merges:-0}" -eq 0 ] && { [ "$rc" -eq 2 ] || [ "$runner" = verify_slurm ]; }; then
    pass "$runner: shards that wrote no part (bad input) stop the run before the merge, OUTDIR as it was"
  else
    fail "$runner: shards without parts: exit $rc, $merges merges"
  fi
  reset
  seed
  STUB_MERGE_RC=1 run 2 "$work/out" scene.yaml > /dev/null 2>&1
  rc=$?
  if [ "$runner" != verify_slurm ] && [ "$rc" -ne 1 ]; then
    fail "$runner: a merge ending 1 (failed checks) gives exit $rc"
  elif grep -q "new --json" "$work/out/summary.json" && [ "$(cat "$work/out/part-0.json")" = '{}' ]; then
    pass "$runner: a merge ending 1 (failed checks) publishes its outputs and parts"
  else
    fail "$runner: a merge ending 1 did not publish"
  fi
  ls -a "$work/out" | grep -q crossdyn-run && fail "$runner: a run folder was left after a finished run"
done

# verify_slurm.sh: sweep tables are written into the run folder, never with `>` into OUTDIR.
reset
mkdir -p "$work/out"
echo "old table" > "$work/out/converge.txt"
echo "old json" > "$work/out/converge.json"
STUB_MERGE_RC=2 PATH=$work/bin:$PATH CROSSDYN=$stub "$src/scripts/verify_slurm.sh" converge 2 "$work/out" s.yaml > /dev/null 2>&1
[ "$(cat "$work/out/converge.txt")" = "old table" ] && [ "$(cat "$work/out/converge.json")" = "old json" ] &&
  pass "verify_slurm: a refused converge merge leaves the old table (not a 0-byte one)" ||
  fail "verify_slurm: converge table after a refused merge: '$(cat "$work/out/converge.txt")'"

# verify_slurm.sh: the role is explicit.
reset
SLURM_ARRAY_TASK_ID=0 SLURM_JOB_ID=7 PATH=$work/bin:$PATH CROSSDYN=$stub \
  "$src/scripts/verify_slurm.sh" 2 "$work/out" s.yaml > "$work/submit.txt" 2>&1
grep -q "^shards: job array" "$work/submit.txt" && [ -f "$work/out/summary.json" ] &&
  pass "verify_slurm: Slurm variables in a submission's environment do not make it a task" ||
  fail "verify_slurm: with SLURM_ARRAY_TASK_ID set the submission acted otherwise: $(cat "$work/submit.txt")"
reset
mkdir -p "$work/out/.crossdyn-run.x"
printf '%s\0' verify 2 "$work/out" "$stub" s.yaml > "$work/out/.crossdyn-run.x/meta"
env -u SLURM_ARRAY_TASK_ID CROSSDYN=$stub "$src/scripts/verify_slurm.sh" --role=task "$work/out/.crossdyn-run.x" > /dev/null 2>&1
rc=$?
[ "$rc" -eq 2 ] && [ "$(calls)" -eq 0 ] && pass "verify_slurm: --role=task outside an array task is refused" ||
  fail "verify_slurm: --role=task without SLURM_ARRAY_TASK_ID: exit $rc, $(calls) calls"
"$src/scripts/verify_slurm.sh" --role=bogus x > /dev/null 2>&1
[ $? -eq 2 ] && pass "verify_slurm: an unknown role is refused" || fail "verify_slurm: unknown role accepted"

# One real run through sweep_parallel.sh: the merge equals an unsharded verify (run times aside).
cd "$src" || exit 1
rm -rf "$work/real"
CROSSDYN=$real "$src/scripts/sweep_parallel.sh" verify 2 "$work/real" torque_free_asymmetric dual_spin > /dev/null 2>&1
rc=$?
"$real" verify --quiet --json "$work/whole.json" torque_free_asymmetric dual_spin > /dev/null 2>&1
python3 - "$work/real/summary.json" "$work/whole.json" <<'PY' && [ "$rc" -eq 0 ] &&
import json, sys
def scrub(o):
    if isinstance(o, dict):
        return {k: scrub(v) for k, v in o.items() if k != "wall_seconds"}
    if isinstance(o, list):
        return [scrub(v) for v in o]
    return o
a, b = (scrub(json.load(open(p))) for p in sys.argv[1:])
sys.exit(0 if a == b else 1)
PY
  pass "sweep_parallel.sh verify with crossdyn: merged summary = unsharded" ||
  fail "sweep_parallel.sh verify with crossdyn: exit $rc or the summaries differ"

echo "$failures failure(s)"
[ "$failures" -eq 0 ]
