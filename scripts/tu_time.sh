#!/bin/bash
# A compiler launcher that logs the CPU seconds of each compile (docs/development.md "Build time"):
#   cmake -S . -B /tmp/prof -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER_LAUNCHER=$PWD/scripts/tu_time.sh
#   TU_TIME_LOG=/tmp/tu.log cmake --build /tmp/prof -j2
#   awk '{print $1 + $2, $5}' /tmp/tu.log | sort -n -r | head     # the heaviest translation units
# Each line: user s, system s, wall s, peak RSS kB, the object file.
out=""
prev=""
for a in "$@"; do
  [ "$prev" = "-o" ] && out="$a"
  prev="$a"
done
exec /usr/bin/time -a -o "${TU_TIME_LOG:-/tmp/tu.log}" -f "%U %S %e %M $out" "$@"
