#!/bin/bash
# Splats as planar quads (depth from the rasterizer, early depth test) against the screen-space rectangles with frag_depth.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
[ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ] && export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /tmp/b /tmp/xdg; tar xJf .devpkg/devbin.tar.xz -C /tmp/b; export XDG_RUNTIME_DIR=/tmp/xdg
for b in old new old new; do echo "== $b"; timeout 40 /tmp/b/render_$b --bench --warm-up-time 1 --measurement-time 2 'render/1920x1080' 2>&1 | grep -E "^render|time:" | grep -v "%"; done | tee $OUT/planar.log
