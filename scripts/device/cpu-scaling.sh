#!/usr/bin/env bash
# Issue 45's many-core figures in one call on a lent machine, from the kit of
# scripts/gpu-kit.sh: the `scaling` table (PBF 10k and 100k, DFSPH 10k, the
# anisotropic extraction at 10k and 100k, for 1, 2, 4, 8 and 16 threads) and
# its `--sweep`, for this build and, where the kit holds one, a build from
# before the team (`scaling-base`), alternated; the 10k PBF substep station
# by station (`pbf_stations`) at each thread count, which shows whether the
# grid build (at most four parts in a team below 32k particles) is what
# stops the scaling (docs/benchmark-notes.md, "The grid build by ranges of
# cells"); then `dam-break-fine` end to end through the demo at each
# thread count. Logs go to $OUT (default
# gpu-bench-out/); each run has its own time limit, so a slow one leaves the
# others' logs.
#
#   scripts/gpu-kit.sh                                  # here
#   BASE=3cabb4b scripts/device/cpu-scaling.sh --kit    # here: add scaling-base
#   scripts/device/cpu-scaling.sh --kit-patch P         # here: add *-patched
#   OUT=$OUT scripts/device/cpu-scaling.sh              # there
#
# `--kit-patch P` builds `scaling` and `pbf_stations` from HEAD with the
# patch P applied (docs/attempts/: a change measured neutral on two cores
# and built for many) as `scaling-patched` and `pbf_stations-patched`,
# which the run then alternates with this build's.
#
# FRAMES (default 10) sets the frames each row times; THREADS (default
# "1 2 4 8 16") the demo's thread counts.
set -euo pipefail
cd "$(dirname "$0")/../.."
kit=.gpu-kit

if [ "${1:-}" = "--kit" ]; then
    # Builds `scaling` at $BASE in a worktree, in this checkout's target
    # directory (its dependencies are built already; the example binary
    # there is then the base's until the next build), and strips it into
    # the kit.
    base=${BASE:?set BASE to the commit to compare with}
    target=${CARGO_TARGET_DIR:-$PWD/target}
    dir=$(mktemp -d)
    mkdir -p "$kit"
    git worktree add -f "$dir" "$base" >/dev/null
    trap 'git worktree remove --force "$dir"' EXIT
    (cd "$dir" && CARGO_TARGET_DIR="$target" cargo build --release --example scaling)
    strip -o "$kit/scaling-base" "$target/release/examples/scaling"
    echo "packed $kit/scaling-base from $base"
    exit 0
fi

if [ "${1:-}" = "--kit-patch" ]; then
    # As --kit, at HEAD with the patch applied.
    patch=$(realpath "${2:?give the patch to apply}")
    target=${CARGO_TARGET_DIR:-$PWD/target}
    dir=$(mktemp -d)
    mkdir -p "$kit"
    git worktree add -f --detach "$dir" HEAD >/dev/null
    trap 'git worktree remove --force "$dir"' EXIT
    (cd "$dir" && git apply "$patch" &&
        CARGO_TARGET_DIR="$target" cargo build --release --example scaling &&
        CARGO_TARGET_DIR="$target" cargo build --release -p sph-core --example pbf_stations)
    for bin in scaling pbf_stations; do
        strip -o "$kit/$bin-patched" "$target/release/examples/$bin"
    done
    echo "packed $kit/scaling-patched and $kit/pbf_stations-patched: HEAD with $patch"
    exit 0
fi

export OUT=${OUT:-gpu-bench-out}
mkdir -p "$OUT"
frames=${FRAMES:-10}
lscpu >"$OUT/lscpu.txt" 2>&1 || true
nproc >>"$OUT/lscpu.txt"

# run LIMIT LOG COMMAND...: the command's output in $OUT/LOG, cut off after
# LIMIT seconds.
run() {
    local limit=$1 log=$2
    shift 2
    echo "== $* ($(date -u +%H:%M:%S))" >"$OUT/$log"
    timeout "$limit" "$@" >>"$OUT/$log" 2>&1 || echo "exit $? (timeout gives 124)" >>"$OUT/$log"
}

builds=(scaling)
[ -x "$kit/scaling-base" ] && builds+=(scaling-base)
[ -x "$kit/scaling-patched" ] && builds+=(scaling-patched)
for round in 1 2; do
    for build in "${builds[@]}"; do
        run 120 "$build-table-$round.log" "$kit/$build" --frames "$frames"
    done
done
for build in "${builds[@]}"; do
    run 150 "$build-sweep.log" "$kit/$build" --sweep --frames "$frames"
done

# Where a 10k PBF substep's time goes at each thread count.
for threads in ${THREADS:-1 2 4 8 16}; do
    for stations in pbf_stations pbf_stations-patched; do
        [ -x "$kit/$stations" ] || continue
        RAYON_NUM_THREADS=$threads run 90 "${stations/pbf_/}-$threads.log" "$kit/$stations"
    done
done

# The demo end to end on the CPU path (`--cpu`: on a hardware adapter the
# demo would step and extract on the GPU): step and extraction
# milliseconds per simulated second from frames.csv (the renderer's own
# time left out, as the issue's table has it). A run cut off by its limit
# is marked, its whole rows summed.
for threads in ${THREADS:-1 2 4 8 16}; do
    dir="$OUT/demo-$threads"
    run 60 "demo-$threads.log" "$kit/sph-app" --headless --cpu --scene dam-break-fine \
        --threads "$threads" --seconds 1 --fps 60 --width 64 --height 48 --out "$dir"
    if [ -f "$dir/frames.csv" ]; then
        cut=""
        grep -q "^exit 124" "$OUT/demo-$threads.log" && cut=" (cut off by its limit)"
        awk -F, -v t="$threads" -v cut="$cut" 'NR > 1 && NF >= 7 && $2 > 0 { s += $6; e += $7; n++; last = $2 }
            END { if (last > 0) printf "threads %s: step %.3f, extraction %.3f, both %.3f wall s per simulated s (%d frames)%s\n",
                t, s / 1000 / last, e / 1000 / last, (s + e) / 1000 / last, n, cut }' \
            "$dir/frames.csv" >>"$OUT/demo-summary.txt"
        rm -f "$dir"/*.png
    fi
done

tail -n 30 "$OUT"/*-table-*.log "$OUT"/*-sweep.log
tail -n 9 "$OUT"/stations*-*.log 2>/dev/null || true
cat "$OUT/demo-summary.txt" 2>/dev/null || true
