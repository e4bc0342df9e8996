#!/bin/bash
# One lent H200 (or H100) call, three things:
# 1. issue 44: both splat paths per pass at 20k, 100k and 1M surfels at
#    1280x720 and 1920x1080 (GPU timestamps), the render bench's 1080p rows
#    of both paths, a frame of drop through each path
#    (scripts/device/compute-splats.sh);
# 2. issue 45: the scaling example on the machine's 16 cores (the "before");
# 3. issue 44 item 4: the demo with no path flag on a hardware adapter.
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out} XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p "$OUT" /tmp/xdg
scripts/device/compute-splats.sh
lscpu | grep -E "Model name|^CPU\(s\)" | tee "$OUT/cpu.txt"
timeout 200 .gpu-kit/scaling --frames 10 2>&1 | tee "$OUT/scaling.log"
timeout 60 .gpu-kit/sph-app --headless --scene drop --seconds 3 --fps 1 --width 960 --height 540 \
    --out /tmp/s-default >"$OUT/default-path.log" 2>&1
echo "rc=$? default"; tail -5 "$OUT/default-path.log"
cp /tmp/s-default/frame_00002.png "$OUT/drop-3s-default.png"
