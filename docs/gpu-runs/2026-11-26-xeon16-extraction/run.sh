#!/bin/bash
# The anisotropic extraction on the lent machine's CPU cores (no GPU used).
mkdir -p /work; [ -e /work/main ] || ln -s "$PWD" /work/main
mkdir -p /tmp/b; tar xJf .devpkg/devbin.tar.xz -C /tmp/b
nproc; lscpu | grep -E "Model name|^CPU\(s\)|Thread"
cd /work/main
for t in 16 2; do
  echo "== RAYON_NUM_THREADS=$t"
  RAYON_NUM_THREADS=$t /tmp/b/stage_times 100k anisotropic 2 11
  RAYON_NUM_THREADS=$t /tmp/b/stage_times 100k 2 11
  RAYON_NUM_THREADS=$t /tmp/b/stage_times drop anisotropic 2 21
done > $OUT/stages.log 2>&1
grep -vE "^  extract" $OUT/stages.log
timeout 200 /tmp/b/extraction_bench --bench --warm-up-time 1 --measurement-time 3 'iterations/2$|anisotropic' > $OUT/bench.log 2>&1
grep -E "time:|thrpt:|^extraction/" $OUT/bench.log
