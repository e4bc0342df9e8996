#!/bin/bash
# Prepared for a lent H100/H200 (issue 44): both splat paths per pass at
# 20k, 100k and 1M surfels at 1280x720 and 1920x1080 (examples/splat_passes,
# GPU timestamps), then the render bench's rows of both paths, and a frame
# of drop through each path to compare. Build the kit here first
# (scripts/gpu-kit.sh), carry .gpu-kit, copy the logs to
# docs/gpu-runs/<date>-<card>-compute-splats/ with this script.
set -u
cd "$(dirname "$0")/../.."
export OUT=${OUT:-gpu-bench-out} XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p "$OUT" /tmp/xdg
# As scripts/gpu-bench.sh: the kit's loaders where the image lacks them, and
# NVIDIA's ICD where the loader does not look.
if ! grep -q 'libvulkan\.so\.1' < <(ldconfig -p) || ! grep -q 'libGLdispatch\.so\.0' < <(ldconfig -p); then
    for f in .gpu-kit/deb/*.deb; do dpkg -x "$f" /; done; ldconfig
fi
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -z "${VK_DRIVER_FILES:-}" ] && [ -f "$icd" ] && export VK_DRIVER_FILES=$icd
nvidia-smi -L; nproc; cat .gpu-kit/COMMIT
for size in "1280 720" "1920 1080"; do
  for n in 20000 100000 1000000; do
    timeout 120 .gpu-kit/splat_passes $n $size
  done
done 2>&1 | tee "$OUT/passes.log"
timeout 240 .gpu-kit/render --bench --warm-up-time 1 --measurement-time 2 'render/(compute-)?1920x1080' \
    >"$OUT/render.log" 2>&1
grep -E "^render/|time:" "$OUT/render.log"
for path in raster compute; do
  timeout 60 .gpu-kit/sph-app --headless --scene drop --seconds 3 --fps 1 --width 960 --height 540 \
      --cpu --splats $path --out /tmp/s-$path >/tmp/s-$path.log 2>&1
  echo "rc=$? $path"; cp /tmp/s-$path/frame_00002.png "$OUT/drop-3s-$path.png"
done
