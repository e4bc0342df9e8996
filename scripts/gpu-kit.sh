#!/usr/bin/env bash
# Packs what a GPU machine without a Rust toolchain or network access needs to
# run the GPU benches (`render` and `gpu`), the `realtime`, `scaling` and
# `splat_passes` examples and the demo (`sph-app`) into .gpu-kit/
# (git-ignored): the six
# binaries, stripped, and
# Debian's Vulkan loader and glvnd packages. Copy the repository with
# .gpu-kit/ to that machine (same x86-64 Linux, glibc 2.35 or later) and run
# scripts/gpu-bench.sh there.
#
#   scripts/gpu-kit.sh            # here: build and pack (about 50 MB)
#   scripts/gpu-bench.sh render   # there: see that script
set -euo pipefail
cd "$(dirname "$0")/.."
kit=.gpu-kit
rm -rf "$kit"
mkdir -p "$kit/deb"

# Cargo's JSON messages name each bench binary: the "executable" of the
# artifact whose target is named after the bench (the realtime example too:
# its `pbf-gpu` column).
json=$(CARGO_TERM_COLOR=never cargo bench --bench gpu --bench render --no-run --message-format=json
    CARGO_TERM_COLOR=never cargo build --release --example realtime --example scaling --bin sph-app --message-format=json
    CARGO_TERM_COLOR=never cargo build --release -p splat-render --example splat_passes --message-format=json
    CARGO_TERM_COLOR=never cargo build --release -p sph-core --example pbf_stations --message-format=json)
for bench in gpu render realtime scaling sph-app splat_passes pbf_stations; do
    exe=$(printf '%s\n' "$json" |
        sed -n "s|.*\"target\":{[^}]*\"name\":\"$bench\".*\"executable\":\"\([^\"]*\)\".*|\1|p" | tail -1)
    [ -n "$exe" ] || { echo "gpu-kit: no executable for bench $bench" >&2; exit 1; }
    strip -o "$kit/$bench" "$exe"
done

# The Vulkan loader and glvnd's libraries of this machine's distribution,
# for a machine whose image has the NVIDIA driver but not them; the run
# script unpacks them only where one is missing. apt's lists and cache go to
# /tmp, leaving the system's alone.
o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64
    -oDir::State::Lists=/tmp/gpu-kit-apt/lists -oDir::Cache=/tmp/gpu-kit-apt/cache
    -oAPT::Sandbox::User=root)
mkdir -p /tmp/gpu-kit-apt/lists/partial /tmp/gpu-kit-apt/cache/archives/partial
apt-get "${o[@]}" update -q >/dev/null
# NVIDIA's Vulkan ICD (libGLX_nvidia) loads glvnd's libraries: the H100
# runs of 2026-11-26 found no adapter without them.
(cd "$kit/deb" && apt-get "${o[@]}" download libvulkan1 libglvnd0 libglx0 libegl1 libgl1 libgles2 libopengl0)

# The commit the binaries were built from, marked when the tree had changes.
{ git rev-parse HEAD; git diff --quiet HEAD || echo "with uncommitted changes"; } | paste -sd' ' >"$kit/COMMIT"
du -sh "$kit"
