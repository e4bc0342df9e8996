#!/bin/bash
# GPU PBF in cell order (commit e1ab64d) on a lent H100: the frame benches
# and profiles at 10k, 100k and 1M, and the realtime pbf-gpu column (the CPU
# rows of the same machine kind are in ../2026-11-26-h100-pbf).
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out} XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p "$OUT" /tmp/xdg
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
SPH_GPU_SIZES=10k,100k,1M SPH_PROFILE_RUNS=5 timeout 200 scripts/gpu-bench.sh gpu \
    --warm-up-time 1 --measurement-time 3 'pbf_frame/' >"$OUT/pbf-frames.log" 2>&1
timeout 200 scripts/gpu-bench.sh realtime --solvers pbf-gpu --max-particles 1100000 --seconds 1 \
    >"$OUT/realtime-pbf-gpu.log" 2>&1
grep -E "pbf:|GPU span|wall:|on the CPU|time:|particles" "$OUT/pbf-frames.log"
cat "$OUT/realtime-pbf-gpu.log"
