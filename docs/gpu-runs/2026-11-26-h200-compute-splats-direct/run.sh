#!/bin/bash
# Second lent H200 call of the session (issue 44): the compute splat path
# with its resolve pass gone (the shade pass reads its buffers). Per-pass
# GPU times of both paths at 20k, 100k and 1M surfels at 1280x720 and
# 1920x1080; the render bench's `drawn` rows (no upload) and 1080p `render`
# rows of both paths; drop through the default path (now compute on a GPU)
# and through raster, to compare.
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out} XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p "$OUT" /tmp/xdg
if ! grep -q 'libvulkan\.so\.1' < <(ldconfig -p) || ! grep -q 'libGLdispatch\.so\.0' < <(ldconfig -p); then
    for f in .gpu-kit/deb/*.deb; do dpkg -x "$f" /; done; ldconfig
fi
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -z "${VK_DRIVER_FILES:-}" ] && [ -f "$icd" ] && export VK_DRIVER_FILES=$icd
nvidia-smi -L; cat .gpu-kit/COMMIT
for size in "1280 720" "1920 1080"; do
  for n in 20000 100000 1000000; do
    timeout 120 .gpu-kit/splat_passes $n $size
  done
done 2>&1 | tee "$OUT/passes.log"
timeout 240 .gpu-kit/render --bench --warm-up-time 1 --measurement-time 2 \
    '^(drawn|render)/(compute-)?1920x1080' >"$OUT/render.log" 2>&1
grep -E "^(render|drawn)/|time:|thrpt:" "$OUT/render.log"
for path in raster auto; do
  timeout 60 .gpu-kit/sph-app --headless --scene drop --seconds 3 --fps 1 --width 960 --height 540 \
      --splats $path --out /tmp/s-$path >"$OUT/drop-$path.log" 2>&1
  echo "rc=$? $path"; cp /tmp/s-$path/frame_00002.png "$OUT/drop-3s-$path.png"
done
