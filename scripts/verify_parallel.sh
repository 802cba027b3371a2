#!/usr/bin/env bash
# Sharded `crossdyn verify` on one machine: N shards at once, then `crossdyn merge`
# (docs/sharding.md).
#
#   scripts/verify_parallel.sh N OUTDIR [verify options and scenes ...]
#
# writes OUTDIR/part-K.json (K = 0 .. N-1), OUTDIR/summary.json and OUTDIR/junit.xml. It is
# `scripts/sweep_parallel.sh verify N OUTDIR ...`, which states the promises (arguments passed
# unchanged, N and OUTDIR checked first, OUTDIR unchanged unless the merge succeeds, a shard with
# failed checks still merged); the merge's exit status is the verdict of the whole run (0 pass,
# 1 a check failed, 2 bad input or parts that do not belong together, 3 an error).
# CROSSDYN names the program (default: crossdyn on PATH, else build/crossdyn of this source tree).
set -uo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 N OUTDIR [verify options and scenes ...]" >&2
  exit 2
fi
export CROSSDYN=${CROSSDYN:-$(command -v crossdyn || echo "$(dirname "$0")/../build/crossdyn")}
exec "$(dirname "$0")/sweep_parallel.sh" verify "$@"
