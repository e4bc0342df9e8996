#!/usr/bin/env bash
# Packs what a GPU machine without a Rust toolchain or network access needs to
# run the GPU benches (`render` and `gpu`) into .gpu-kit/ (git-ignored):
# the two criterion bench binaries, stripped, and Debian's Vulkan loader
# package. Copy the repository with .gpu-kit/ to that machine (same x86-64
# Linux, glibc 2.35 or later) and run scripts/gpu-bench.sh there.
#
#   scripts/gpu-kit.sh            # here: build and pack (about 20 MB)
#   scripts/gpu-bench.sh render   # there: see that script
set -euo pipefail
cd "$(dirname "$0")/.."
kit=.gpu-kit
rm -rf "$kit"
mkdir -p "$kit/deb"

# Cargo names each bench binary on stderr: "Executable benches/gpu.rs (target/…/gpu-HASH)".
log=$(cargo bench --bench gpu --bench render --no-run 2>&1 | tee /dev/stderr)
for bench in gpu render; do
    exe=$(printf '%s\n' "$log" | sed -n "s|.*Executable benches/$bench\.rs (\(.*\))|\1|p" | tail -1)
    [ -n "$exe" ] || { echo "gpu-kit: no executable for bench $bench" >&2; exit 1; }
    strip -o "$kit/$bench" "$exe"
done

# The Vulkan loader, for a machine whose image has the NVIDIA driver but no
# libvulkan.so.1; the run script unpacks it only where none is installed.
o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/gpu-kit-apt-lists)
mkdir -p /tmp/gpu-kit-apt-lists/partial
apt-get "${o[@]}" update -q >/dev/null
(cd "$kit/deb" && apt-get "${o[@]}" download libvulkan1)

git rev-parse HEAD >"$kit/COMMIT"
du -sh "$kit"
