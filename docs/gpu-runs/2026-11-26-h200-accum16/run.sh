#!/bin/bash
# Experiment: the attribute pass's accumulation target in Rgba32Float (default) and Rgba16Float.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ] && export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /tmp/b /tmp/xdg; tar xJf .devpkg/devbin.tar.xz -C /tmp/b
export XDG_RUNTIME_DIR=/tmp/xdg
for v in f32 f16 f32 f16; do
  echo "== $v"
  if [ $v = f16 ]; then export SPH_ACCUM_F16=1; else unset SPH_ACCUM_F16; fi
  timeout 60 /tmp/b/render --bench --warm-up-time 1 --measurement-time 2 'render/1920x1080' 2>&1 | grep -E "^render|time:" 
done 2>&1 | tee $OUT/accum.log
