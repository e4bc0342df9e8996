#!/bin/bash
# Issue 43's figures on a lent H100 (one call): the kit of scripts/gpu-kit.sh,
# then (1) the PBF frame benches and realtime rows (scripts/device-gpu-pbf.sh),
# (2) the demo headless, CPU path on 16 cores beside the GPU path (PBF, the
# scenes' default), 1 simulated second at 60 fps, two runs each, and
# (3) frames of `drop` at 3 s from both paths, to look at.
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out} XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p "$OUT" /tmp/xdg
# The NVIDIA ICD needs glvnd's libraries, which the image lacks (the GPU
# README's loaders, carried in .gl/).
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
timeout 300 scripts/device-gpu-pbf.sh || echo "device-gpu-pbf: rc=$?"
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -f "$icd" ] && export VK_DRIVER_FILES=$icd
app=.gpu-kit/sph-app
sum() { awk -F, 'NR==1{for(i=1;i<=NF;i++){if($i=="step_ms")s=i;if($i=="extract_ms")e=i;if($i=="render_ms")r=i}} NR>1{S+=$s;E+=$e;R+=$r;n++} END{printf "%d frames: step %.3f s, extract %.3f s, render %.3f s\n", n, S/1000, E/1000, R/1000}' "$1/frames.csv"; }
for run in 1 2; do
  for args in "--scene drop" "--scene drop --gpu-sim --gpu-extract" \
      "--scene dam-break-fine" "--scene dam-break-fine --gpu-sim --gpu-extract" "--scene dam-break-fine --gpu-sim"; do
    d=/tmp/o$RANDOM; t0=$(date +%s%N)
    timeout 60 $app --headless $args --seconds 1 --fps 60 --width 64 --height 48 --out $d >$d.log 2>&1
    rc=$?; wall=$(( ($(date +%s%N) - t0) / 1000000 ))
    echo "rc=$rc $args: $(sum $d 2>&1); wall $wall ms with start-up"
  done
done 2>&1 | tee "$OUT/demo.log"
for path in cpu gpu; do
  extra=""; [ $path = gpu ] && extra="--gpu-sim --gpu-extract"
  timeout 60 $app --headless --scene drop $extra --seconds 3 --fps 1 --width 960 --height 540 --out /tmp/f$path >/tmp/f$path.log 2>&1
  echo "rc=$? frames $path"; tail -1 /tmp/f$path.log; cp /tmp/f$path/frame_00002.png "$OUT/drop-3s-$path.png" 2>/dev/null
done 2>&1 | tee -a "$OUT/demo.log"
