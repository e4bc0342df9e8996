#!/bin/bash
# The GPU anisotropic extraction (issue 44) on a lent H100: the gpu bench's
# extraction, PBF frame and PBF frame + extraction + 1080p groups on the GPU
# at 100k and 1M with their per-pass profiles, then the demo's GPU path
# (PBF, anisotropic surface) on drop and dam-break-fine, and a frame of
# drop at 3 s to look at. The kit: scripts/gpu-kit.sh (gpu, sph-app).
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out} XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p "$OUT" /tmp/xdg
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
nvidia-smi -L; nproc; cat .gpu-kit/COMMIT
SPH_GPU_SIZES=100k,1M SPH_PROFILE_RUNS=5 timeout 300 .gpu-kit/gpu --bench \
    --warm-up-time 1 --measurement-time 3 '(extraction|pbf_frame|pbf_frame_1080p)/gpu' \
    >"$OUT/gpu.log" 2>&1
grep -E "pbf:|extract|GPU span|time:|particles|surfels|scene pass|visibility|attribute|normalise" "$OUT/gpu.log"
app=.gpu-kit/sph-app
sum() { awk -F, 'NR==1{for(i=1;i<=NF;i++){if($i=="step_ms")s=i;if($i=="extract_ms")e=i;if($i=="render_ms")r=i;if($i=="surfels")n=i}} NR>1{S+=$s;E+=$e;R+=$r;N+=$n;c++} END{printf "%d frames: step %.3f s, extract %.3f s, render %.3f s, %.0f surfels a frame\n", c, S/1000, E/1000, R/1000, N/c}' "$1/frames.csv"; }
for run in 1 2; do
  for args in "--scene drop --gpu-sim --gpu-extract" "--scene dam-break-fine --gpu-sim --gpu-extract" \
      "--scene drop --gpu-sim --gpu-extract --surface isotropic" "--scene dam-break-fine --gpu-sim --gpu-extract --surface isotropic"; do
    d=/tmp/o$RANDOM; t0=$(date +%s%N)
    timeout 60 $app --headless $args --seconds 1 --fps 60 --width 64 --height 48 --out $d >$d.log 2>&1
    rc=$?; wall=$(( ($(date +%s%N) - t0) / 1000000 ))
    echo "rc=$rc $args: $(sum $d 2>&1); wall $wall ms with start-up"
  done
done 2>&1 | tee "$OUT/demo.log"
timeout 60 $app --headless --scene drop --gpu-sim --gpu-extract --seconds 3 --fps 1 --width 960 --height 540 --out /tmp/fg >/tmp/fg.log 2>&1
echo "rc=$? frames"; tail -1 /tmp/fg.log; cp /tmp/fg/frame_00002.png "$OUT/drop-3s-gpu-anisotropic.png"
