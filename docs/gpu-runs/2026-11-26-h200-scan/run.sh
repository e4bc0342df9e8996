#!/bin/bash
# Device check after the parallel block-sum scan: GPU tests, then the gpu bench.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ] && export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /work; [ -e /work/main ] || ln -s "$PWD" /work/main
mkdir -p /tmp/b /tmp/xdg; tar xJf .devpkg/devbin.tar.xz -C /tmp/b
export SPH_REQUIRE_GPU=1 XDG_RUNTIME_DIR=/tmp/xdg
nvidia-smi -L
cd /work/main
for t in equivalence extraction; do
  echo "== $t"; timeout 150 /tmp/b/$t --nocapture 2>&1 | grep -vE "^\s*$" | tail -25
done > $OUT/tests.log 2>&1
grep -E "^== |test result|FAILED|panicked|buckets" $OUT/tests.log
timeout 300 /tmp/b/gpu --bench --warm-up-time 1 --measurement-time 2 > $OUT/gpu.log 2>&1
grep -E "scan_block_sums|GPU span|^(sph_step|frame_1080p|extraction)/[a-z_]+/[0-9kM]+ +time|time:" $OUT/gpu.log | head -60
