#!/bin/bash
# The standard stability maps of issue 13, as committed in reports/example/stability/: one
# `crossdyn stability` command per map. Usage: scripts/stability_examples.sh [OUT_DIR]
# (default /tmp/stability_examples). About 75 s on 2 free cores (80.7 s measured 2026-11-27 with
# --jobs 2 and the maps one after another; 380-400 s before issue 24 item 4). The maps run in two
# lanes of one thread each (--jobs 1), so that a map's report (Python, one core) overlaps the other
# lane's runs and no run gets less than a core (a wall-clock --timeout means what it says); the
# lanes hold about the same CPU time (about 73 s each).
set -euo pipefail
C=${CROSSDYN:-build/crossdyn}
O=${1:-/tmp/stability_examples}
mkdir -p "$O"
lane_a() {
# Long horizons, with newton-euler's constraint stabilisation none / baumgarte / projection.
$C stability chain5 --vary duration --values 10,100,1000 --engines kane,lagrange,newton-euler:none,newton-euler:baumgarte,newton-euler:projection --integrators dopri5,dop853 --tolerances 1e-6,1e-9,1e-12 --accuracy 1e-6 --timeout 120 --jobs 1 -q --report "$O/horizon" > "$O/horizon.txt"
# Where the implicit method wins: the array's modes 1000 x stiffer, damped from 0.5 % to twice
# critical (decaying stiff modes, which BDF steps over and an explicit method must resolve).
$C stability hub_flex_array --set array.modal_stiffness=1000 --vary array.modal_damping --values 0.005,0.05,0.5,2 --duration 6 --accuracy 1e-6 --timeout 60 --jobs 1 -q --report "$O/damping" > "$O/damping.txt"
# Fast rotors: the wheel from 10 rad/s to 10,000 rpm.
$C stability dual_spin --vary bearing.rate --values 10,104.7,314,1047 --duration 5 --accuracy 1e-6 --jobs 1 -q --report "$O/rotor" > "$O/rotor.txt"
# Euler-angle lock: lagrange with and without re-charting, runs that end before and after the lock.
$C stability gimbal_lock --vary duration --values 1,2,3,5 --engines kane,lagrange,lagrange:no-rechart,newton-euler --integrators dopri5,dop853 --tolerances 1e-6,1e-9,1e-12 --jobs 1 -q --report "$O/lock" > "$O/lock.txt"
}

lane_b() {
# Explicit steppers against a hinge spring's stiffness: the rk4 limit h |lambda|max ~ 2.8.
$C stability hub_two_panels --vary hinge1.stiffness --values 500..5e6 --timeout 60 --jobs 1 -q --report "$O/hinge" > "$O/hinge.txt"
# A stiff flexible appendage: the solar array's modal stiffness x 1 ... x 1e4 (EI x 1e4).
$C stability hub_flex_array --vary array.modal_stiffness --values 1..1e4 --duration 6 --accuracy 1e-6 --timeout 60 --jobs 1 -q --report "$O/modal" > "$O/modal.txt"
# Chain length.
$C stability chain5 --vary links --values 2,4,8,16 --duration 2 --jobs 1 -q --report "$O/chain" > "$O/chain.txt"
# How close the pass comes to the lock: the wobble wx from 0.02 rad/s to none (wz = 0: with wx = 0
# the body spins about y alone and its x axis passes through the lock itself).
$C stability gimbal_lock --set base.wz=0 --vary base.wx --values 2e-2,2e-3,2e-4,2e-5,2e-6,0 --engines kane,lagrange,lagrange:no-rechart,newton-euler --integrators dopri5,dop853 --tolerances 1e-6,1e-9,1e-12 --jobs 1 -q --report "$O/lock_pass" > "$O/lock_pass.txt"
}

lane_a & a=$!
lane_b & b=$!
status=0
wait "$a" || status=$?
wait "$b" || status=$?
[ "$status" -eq 0 ] || { echo "stability_examples.sh: a map failed (exit status $status)" >&2; exit "$status"; }
echo "maps in $O"
