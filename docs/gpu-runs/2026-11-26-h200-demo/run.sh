#!/bin/bash
# The demo on the lent machine: CPU paths on 16 cores, and the GPU paths.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ] && export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /work; [ -e /work/main ] || ln -s "$PWD" /work/main
mkdir -p /tmp/b /tmp/xdg; tar xJf .devpkg/devbin.tar.xz -C /tmp/b
export XDG_RUNTIME_DIR=/tmp/xdg
sum() { awk -F, 'NR==1{for(i=1;i<=NF;i++){if($i=="step_ms")s=i;if($i=="extract_ms")e=i;if($i=="render_ms")r=i}} NR>1{S+=$s;E+=$e;R+=$r;n++} END{printf "%d frames: step %.3f s, extract %.3f s, render %.3f s per run\n", n, S/1000, E/1000, R/1000}' $1/frames.csv; }
for run in 1 2; do
for args in "--scene drop" "--scene drop --surface isotropic" "--scene dam-break-fine" "--scene dam-break-fine --surface isotropic" "--scene drop --gpu-sim --gpu-extract" "--scene dam-break-fine --gpu-sim --gpu-extract"; do
  d=/tmp/o$RANDOM; /tmp/b/sph-app --headless $args --seconds 1 --fps 60 --width 64 --height 48 --out $d > $d.log 2>&1; echo "rc=$? $args: $(sum $d)"
done; done | tee $OUT/demo.log
/tmp/b/sph-app --headless --scene drop --gpu-sim --gpu-extract --seconds 3 --fps 1 --width 960 --height 540 --out /tmp/gpuframes > /tmp/gpuframes.log 2>&1; echo "rc=$?"; tail -2 /tmp/gpuframes.log
cp /tmp/gpuframes/frame_00002.png $OUT/gpu_drop_3s.png
/tmp/b/sph-app --headless --scene drop --seconds 3 --fps 1 --width 960 --height 540 --out /tmp/cpuframes > /dev/null 2>&1; cp /tmp/cpuframes/frame_00002.png $OUT/cpu_drop_3s.png

# The GPU paths need WCSPH (the GPU step is the thesis's); run in a second call:
# sum() as above; for run in 1 2; do for a in "--scene drop --solver wcsph --gpu-sim --gpu-extract" \
#   "--scene drop --solver wcsph" "--scene dam-break-fine --solver wcsph --gpu-sim --gpu-extract" \
#   "--scene dam-break-fine --solver wcsph"; do d=/tmp/o$RANDOM; /tmp/b/sph-app --headless $a --seconds 1 \
#   --fps 60 --width 64 --height 48 --out $d > $d.log 2>&1; echo "rc=$? $a: $(sum $d)"; done; done | tee $OUT/gpu_demo.log
# and `sph-app --headless --scene drop [--solver wcsph --gpu-sim --gpu-extract] --seconds 3 --fps 1 --width 960 --height 540`,
# the third frame of each tiled into drop-3s-cpu-path-and-gpu-path.png (scripts/tile_png.py).
