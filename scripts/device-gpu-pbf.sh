#!/usr/bin/env bash
# Issue 43's GPU figures in one call on a lent GPU machine, from the kit of
# scripts/gpu-kit.sh (built and carried here first): the whole PBF frame and
# its per-pass profile (`gpu` bench: pbf_frame, pbf_frame_1080p at 100k and
# 1M), and the realtime table's pbf-gpu column beside the CPU's PBF on the
# machine's cores. Logs go to $OUT (default gpu-bench-out/).
#
#   scripts/gpu-kit.sh                      # here
#   OUT=$OUT scripts/device-gpu-pbf.sh      # there
#
# SPH_GPU_SIZES (default 100k,1M), MAX_PARTICLES (1100000) and
# SECONDS_PER_ROW (1) shrink it, e.g. for a smoke test on lavapipe.
set -euo pipefail
cd "$(dirname "$0")/.."
export OUT=${OUT:-gpu-bench-out}
mkdir -p "$OUT"
SPH_PROFILE_RUNS=5 scripts/gpu-bench.sh gpu --warm-up-time 1 --measurement-time 3 'pbf_frame' \
    >"$OUT/pbf-frames.log" 2>&1 || echo "gpu bench failed: see $OUT/pbf-frames.log"
# The realtime rows: PBF on the CPU up to 100k, on the GPU up to 1M, and the
# GPU's real-time count by bisection.
scripts/gpu-bench.sh realtime --solvers pbf,pbf-gpu --max-particles "${MAX_PARTICLES:-1100000}" \
    --seconds "${SECONDS_PER_ROW:-1}" \
    >"$OUT/realtime-pbf-gpu.log" 2>&1 || echo "realtime failed: see $OUT/realtime-pbf-gpu.log"
tail -n 40 "$OUT/pbf-frames.log" "$OUT/realtime-pbf-gpu.log"
