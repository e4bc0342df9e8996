#!/bin/bash
# Issue 45: where a scene stops gaining from more threads on the lent
# machine's 16 cores. PBF frames of the slab dam break at about 5k, 10k,
# 20k and 40k particles and DFSPH at 10k, for 1, 2, 4, 6, ..., 16 threads
# (examples/scaling.rs --sweep), twice.
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out}
mkdir -p "$OUT"
lscpu | grep -E "Model name|^CPU\(s\)"; cat .gpu-kit/COMMIT
for run in a b; do
  timeout 140 .gpu-kit/scaling --sweep --frames 10 2>&1 | tee "$OUT/sweep-$run.log"
done
