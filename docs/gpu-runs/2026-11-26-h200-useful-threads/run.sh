#!/bin/bash
# Issue 45: the scaling example before (.gpu-kit/before/, 6cfadc5 plus
# --sweep) and after World steps in a pool of useful_threads(n) threads
# (max(8, n/3000)) when the caller's has more, alternating, twice each.
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out}
mkdir -p "$OUT"
lscpu | grep -E "Model name|^CPU\(s\)"; cat .gpu-kit/COMMIT
for run in a b; do
  for kit in before after; do
    bin=.gpu-kit/scaling; [ $kit = before ] && bin=.gpu-kit/before/scaling
    echo "== $kit $run"
    timeout 110 $bin --frames 10 2>&1 | tee "$OUT/scaling-$kit-$run.log"
  done
done
