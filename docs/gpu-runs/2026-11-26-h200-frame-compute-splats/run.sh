#!/bin/bash
# Issue 43/44: the demo's whole GPU frame (PBF frame, covered anisotropic
# extraction, 1920x1080 image, one submission) with the adapter's splat path
# (now compute) and with raster, at 100k and 1M particles, with per-pass
# GPU profiles; then the demo end to end on its default path.
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
SPH_GPU_SIZES=100k,1M SPH_PROFILE_RUNS=3 timeout 150 .gpu-kit/gpu --bench \
    --warm-up-time 1 --measurement-time 2 'pbf_frame_1080p/gpu_demo' >"$OUT/gpu.log" 2>&1
echo "rc=$?"; grep -E "pbf_frame_1080p/|time:|GPU span|particles" "$OUT/gpu.log" | grep -v "%" | head -40
sum() { awk -F, 'NR==1{for(i=1;i<=NF;i++){if($i=="step_ms")s=i;if($i=="extract_ms")e=i;if($i=="render_ms")r=i;if($i=="surfels")n=i}} NR>1{S+=$s;E+=$e;R+=$r;N+=$n;c++} END{printf "%d frames: step %.3f s, extract %.3f s, render %.3f s, %.0f surfels a frame\n", c, S/1000, E/1000, R/1000, N/c}' "$1/frames.csv"; }
for scene in drop dam-break-fine; do
  timeout 40 .gpu-kit/sph-app --headless --scene $scene --seconds 1 --fps 60 --width 64 --height 48 \
      --out /tmp/d-$scene >"$OUT/demo-$scene.log" 2>&1
  echo "rc=$? $scene: $(sum /tmp/d-$scene 2>&1)"; head -1 "$OUT/demo-$scene.log"
done | tee "$OUT/demo.log"
