#!/usr/bin/env bash
# Quick start, step 1: install what is missing (Debian packages), build the crossdyn program into
# build/ (only the program: the tests are built by step 2, scripts/test.sh), and run the main job
# (verify every scene, write the report). Safe to run again: it only installs what is missing.
#   CROSSDYN_WERROR=ON    treat compiler warnings as errors (CI)
#   CROSSDYN_NO_VERIFY=1  build only
set -euo pipefail
cd "$(dirname "$0")/.."
# Each phase's wall time, printed at the end (issue 29: a result in minutes on a fresh machine).
phase_start=$SECONDS
phases=()
phase_done() { phases+=("$1 $((SECONDS - phase_start)) s"); phase_start=$SECONDS; }
print_phases() {
  [ ${#phases[@]} -eq 0 ] && return
  local text="" p
  for p in "${phases[@]}"; do text+="$p, "; done
  echo "quickstart: ${text}total ${SECONDS} s" >&2
}
trap print_phases EXIT

# The report and `crossdyn draw` run reports/*.py with /usr/bin/python3: matplotlib and Jinja2.
# catch2 is Catch2 v2 on Debian 12 (bookworm); libsundials-dev is SUNDIALS 6.4 (the CVODE
# integrators); libfmt-dev is fmt 9, used header-only (its Dragonbox writes the CSV numbers);
# parallel is GNU parallel (scripts/verify_parallel.sh and its test); ninja-build schedules the
# build (both cores busy to the end; CMake's Makefiles leave one idle while a library links).
# .ci/run uses this list (it runs this script).
packages=(build-essential cmake ninja-build libeigen3-dev libboost-dev libyaml-cpp-dev catch2
          libbenchmark-dev libcli11-dev nlohmann-json3-dev libsundials-dev libfmt-dev
          python3-matplotlib python3-jinja2 parallel)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "Installing Debian packages: ${missing[*]}"
  sudo_cmd=""
  [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq "${missing[@]}"
fi

# Ninja for a new build folder; an existing one keeps the generator it was made with.
generator=()
[ -f build/CMakeCache.txt ] || generator=(-G Ninja)
phase_done packages
cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=Release -DCROSSDYN_WERROR="${CROSSDYN_WERROR:-OFF}"
phase_done configure
cmake --build build -j2 --target crossdyn
phase_done build

if [ -z "${CROSSDYN_NO_VERIFY:-}" ]; then
  build/crossdyn verify --report reports/latest
  phase_done "verify and report"
  echo "Report: reports/latest/index.html"
fi
