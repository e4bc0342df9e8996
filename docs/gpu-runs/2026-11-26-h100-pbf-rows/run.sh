#!/bin/bash
# GPU PBF with row-run neighbour lists (commit in .gpu-kit/COMMIT) on a lent
# H100: the frame benches and profiles at 10k, 100k and 1M (GPU only) and the
# realtime pbf-gpu column, as ../2026-11-26-h100-pbf-box/run.sh.
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out} XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p "$OUT" /tmp/xdg
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
nvidia-smi -L; nproc; cat .gpu-kit/COMMIT
SPH_GPU_SIZES=10k,100k,1M SPH_PROFILE_RUNS=5 timeout 150 .gpu-kit/gpu --bench \
    --warm-up-time 1 --measurement-time 3 'pbf_frame/gpu' >"$OUT/pbf-frames.log" 2>&1
timeout 150 .gpu-kit/realtime --solvers pbf-gpu --max-particles 1100000 --seconds 1 \
    >"$OUT/realtime-pbf-gpu.log" 2>&1
grep -E "pbf:|GPU span|on the CPU|time:|PBF .* substeps" "$OUT/pbf-frames.log"
cat "$OUT/realtime-pbf-gpu.log"
