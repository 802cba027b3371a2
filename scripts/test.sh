#!/usr/bin/env bash
# Quick start, step 2: build everything in build/ (the test programs, the benchmarks) and run the
# whole test suite. Run scripts/quickstart.sh first (it installs the packages and configures build/).
# Arguments are passed to ctest (e.g. -R kane to run some tests only).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -f build/CMakeCache.txt ]; then
  echo "scripts/test.sh: build/ is not configured: run scripts/quickstart.sh first" >&2
  exit 2
fi
start=$SECONDS
cmake --build build -j2
echo "test.sh: build $((SECONDS - start)) s" >&2
start=$SECONDS
status=0
ctest --test-dir build -j2 --output-on-failure "$@" || status=$?
echo "test.sh: ctest $((SECONDS - start)) s" >&2
exit $status
