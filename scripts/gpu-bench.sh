#!/usr/bin/env bash
# Runs the GPU benches packed by scripts/gpu-kit.sh on a machine with a GPU and
# no Rust toolchain, and writes their output to $OUT (or gpu-bench-out/).
#
#   scripts/gpu-bench.sh render [criterion args…]   # `cargo bench --bench render`
#   scripts/gpu-bench.sh gpu [criterion args…]      # `cargo bench --bench gpu`
#   scripts/gpu-bench.sh realtime [args…]           # `cargo run --release --example realtime --`
#
# Extra arguments go to criterion (a filter such as `sph_step/`, or
# `--warm-up-time 1 --measurement-time 5`). The figures are those of the
# commit in .gpu-kit/COMMIT.
set -euo pipefail
cd "$(dirname "$0")/.."
kit=.gpu-kit
bench=${1:?"usage: $0 render|gpu|realtime [args…]"}
shift
[ -x "$kit/$bench" ] || { echo "no $kit/$bench: run scripts/gpu-kit.sh first" >&2; exit 1; }

# (grep reads a process substitution: with pipefail, `ldconfig -p | grep -q`
# fails when grep's early exit kills ldconfig with SIGPIPE.)
if ! grep -q 'libvulkan\.so\.1' < <(ldconfig -p) || ! grep -q 'libGLdispatch\.so\.0' < <(ldconfig -p); then
    for f in "$kit"/deb/*.deb; do dpkg -x "$f" /; done
    ldconfig
fi
# NVIDIA's ICD where the image keeps it outside the loader's search path.
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -z "${VK_DRIVER_FILES:-}" ] && [ -f "$icd" ]; then
    export VK_DRIVER_FILES=$icd
fi

out=${OUT:-gpu-bench-out}
mkdir -p "$out"
{
    echo "commit: $(cat "$kit/COMMIT")"
    nvidia-smi -L 2>/dev/null || true
    nproc
} | tee "$out/$bench-machine.txt"
if [ "$bench" = realtime ]; then
    "$kit/$bench" "$@" 2>&1 | tee "$out/$bench.txt"
else
    "$kit/$bench" --bench "$@" 2>&1 | tee "$out/$bench.txt"
fi
