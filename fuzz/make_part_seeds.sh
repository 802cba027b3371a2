#!/bin/sh
# Writes the merge fuzz target's seeds (fuzz/part_seeds/, format in fuzz/part_input.hpp) from part
# files that CROSSDYN (default: build/crossdyn) writes now, so that the seeds follow the part
# format when it changes: run it after a change to harness/shard.cpp and commit the result.
#   fuzz/make_part_seeds.sh [CROSSDYN]
# The scenes are those of the command-line seeds (fuzz/cli_seeds/study_csv.txt: a hub and a
# panel on a hinge; converge_json.txt: a hub with a two-mode beam), each run for 0.1 s.
set -eu
src=$(cd "$(dirname "$0")/.." && pwd)
crossdyn=$(cd "$(dirname "${1:-$src/build/crossdyn}")" && pwd)/$(basename "${1:-$src/build/crossdyn}")
out=$src/fuzz/part_seeds
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene_of() { sed '1,/^%%$/d' "$src/fuzz/cli_seeds/$1"; }
mkdir "$work/small" "$work/beam"
scene_of study_csv.txt > "$work/small/scene.yaml"
scene_of converge_json.txt > "$work/beam/scene.yaml"

# seed NAME DIR "ARGS (one line, space-separated)" PART...: the arguments, the scene, the parts.
seed() {
  name=$1 dir=$2 args=$3
  shift 3
  {
    for a in $args; do printf '%s\n' "$a"; done
    printf '%%%%\n'
    cat "$work/$dir/scene.yaml"
    for p in "$@"; do
      printf '%%%%\n'
      cat "$work/$dir/$p"
    done
  } > "$out/$name.txt"
}
run() { (cd "$work/$1" && shift && "$crossdyn" "$@" > /dev/null 2>&1) || true; }

run small verify scene.yaml --shard 0/2 --part v0.json -q --no-converge
run small verify scene.yaml --shard 1/2 --part v1.json -q --no-converge
run small study scene.yaml --engines kane,lagrange --integrators rk4,dopri5 --tolerances 1e-4 \
  --dts 0.05 --repeat 1 --shard 0/1 --part s0.json -q
run small stability scene.yaml --vary hinge.stiffness --values 1,10 --engines kane \
  --integrators rk4 --dts 0.05 --duration 0.1 --shard 0/2 --part t0.json -q
run small stability scene.yaml --vary hinge.stiffness --values 1,10 --engines kane \
  --integrators rk4 --dts 0.05 --duration 0.1 --shard 1/2 --part t1.json -q
run beam converge scene.yaml --engine kane --integrator rk4 --dt 0.01 --shard 0/2 --part c0.json -q
run beam converge scene.yaml --engine kane --integrator rk4 --dt 0.01 --shard 1/2 --part c1.json -q
for p in v0 v1 s0 t0 t1; do test -s "$work/small/$p.json" || { echo "no part $p" >&2; exit 1; }; done
for p in c0 c1; do test -s "$work/beam/$p.json" || { echo "no part $p" >&2; exit 1; }; done

seed verify_two_parts small "part0.json part1.json --json m.json --junit m.xml -q" v0.json v1.json
seed verify_reversed small "part1.json part0.json --json m.json" v0.json v1.json
seed verify_missing_shard small "part0.json --json m.json --junit m.xml" v0.json
seed verify_repeated_part small "part0.json part0.json part1.json --json m.json" v0.json v1.json
seed verify_csv_refused small "part0.json part1.json --csv m.csv" v0.json v1.json
seed verify_json_is_a_part small "part0.json part1.json --json part1.json" v0.json v1.json
seed study_one_part small "part0.json --csv m.csv -q" s0.json
seed study_junit_refused small "part0.json --junit m.xml" s0.json
seed stability_two_parts small "part0.json part1.json --csv m.csv -q" t0.json t1.json
# (stability parts merged with --csv scene.yaml, a scene the parts name: fuzz/part_regressions/)
seed converge_two_parts beam "part0.json part1.json --json m.json -q" c0.json c1.json
seed converge_csv_refused beam "part0.json part1.json --csv m.csv" c0.json c1.json
# Parts of different commands together.
cp "$work/small/s0.json" "$work/small/v_s.json"
seed verify_and_study small "part0.json part1.json --json m.json" v0.json v_s.json
echo "$(ls "$out" | wc -l) seeds in $out"
