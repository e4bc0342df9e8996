#!/bin/bash
# Device check: GPU tests and the render and gpu benches on a real GPU.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ] && export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /work; [ -e /work/main ] || ln -s "$PWD" /work/main
mkdir -p /tmp/b /tmp/xdg; tar xJf .devpkg/devbin.tar.xz -C /tmp/b
export SPH_REQUIRE_GPU=1 XDG_RUNTIME_DIR=/tmp/xdg
nvidia-smi -L; nproc; lscpu | grep "Model name"
cd /work/main
for t in sph_gpu equivalence extraction splat_render scene_geometry splatting; do
  echo "== $t"; timeout 150 /tmp/b/$t --nocapture 2>&1 | grep -vE "^\s*$" | tail -25
done > $OUT/tests.log 2>&1
grep -E "^== |test result|FAILED|panicked|adapter" $OUT/tests.log
timeout 150 /tmp/b/render --bench --warm-up-time 1 --measurement-time 2 > $OUT/render.log 2>&1
grep -E "adapter|time:|thrpt:" $OUT/render.log | head -40
timeout 260 /tmp/b/gpu --bench --warm-up-time 1 --measurement-time 2 > $OUT/gpu.log 2>&1
grep -vE "^\s*$|Warming|Collecting|Analyzing|change:|No change|Performance has|Found .* outliers|high (mild|severe)|low (mild|severe)" $OUT/gpu.log | head -80
