#!/bin/bash
# Two GPU PBF builds side by side on one lent H100: (a) afe4dfc, cell-ordered
# working buffers with hashed buckets and the one-vec4 correction; (b)
# af94a28, the same with one bucket per cell of the domain (GpuGrid::in_box).
# Each: the frame benches and profiles at 10k, 100k and 1M (GPU only), and
# the realtime pbf-gpu column. The kit holds (b) and, in a/, (a)'s binaries.
set -u
cd "$(dirname "$0")/../../.."
export OUT=${OUT:-gpu-bench-out} XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p "$OUT" /tmp/xdg
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
nvidia-smi -L; nproc
for kit in a b; do
  dir=.gpu-kit; [ $kit = a ] && dir=.gpu-kit/a
  echo "== $kit: $(cat $dir/COMMIT)"
  SPH_GPU_SIZES=10k,100k,1M SPH_PROFILE_RUNS=5 timeout 150 $dir/gpu --bench \
      --warm-up-time 1 --measurement-time 3 'pbf_frame/gpu' >"$OUT/pbf-frames-$kit.log" 2>&1
  timeout 150 $dir/realtime --solvers pbf-gpu --max-particles 1100000 --seconds 1 \
      >"$OUT/realtime-pbf-gpu-$kit.log" 2>&1
  grep -E "pbf:|GPU span|on the CPU|time:|PBF .* substeps" "$OUT/pbf-frames-$kit.log"
  cat "$OUT/realtime-pbf-gpu-$kit.log"
done
