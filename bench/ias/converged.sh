#!/bin/sh
# converged.sh — the eq-* comparison of `ias` against `reference` (issue 3) measured against a
# converged penumbra render of each crop window instead of the pbrt-v4 image, so that equal-relMSE
# ratios are not bent by the floor the pbrt images set (spectral against RGB rendering, the pbrt
# image's own noise). The converged crop is a fixed-spp `reference` render (CONV_SPP eye rays,
# seed 7; the eq-* cases use seed 0), never a threshold render: a threshold render's stopping rule
# may bias it (issue 21, docs/adaptive-sampling.md). Its own noise is measured by a second render
# with seed 8: `penumbra diff` of the two goes to OUT/converged-SCENE-noise.txt (the relMSE between
# two independent renders is twice each one's own). penumbra_bench compares a reference of the crop
# window's size as it is.
#
#   bench/ias/converged.sh [BUILD_DIR] [OUT_DIR]    (defaults: build, bench/results/ias-converged)
#
# Environment: PN_SHARED (default ../shared), THREADS (default 2), CONV_SPP (default 2048),
# SCENES (default "hall-many:hall staircase-832:stair"), RUNS (default 1), BVH (1: also the light
# BVH cases), REFS_ONLY (1: render the converged crops and their noise, skip the bench).
set -eu
BUILD=${1:-build}
OUT=${2:-bench/results/ias-converged}
SHARED=${PN_SHARED:-../shared}
THREADS=${THREADS:-2}
CONV_SPP=${CONV_SPP:-2048}
SCENES=${SCENES:-hall-many:hall staircase-832:stair}
RUNS=${RUNS:-1}
mkdir -p "$OUT"
CONF="$OUT/eq-converged.conf"
: > "$CONF"
for pair in $SCENES; do
    scene=${pair%%:*}
    key=${pair##*:}
    conv="$OUT/converged-$scene.exr"
    crop=$(grep "^eq-$key-ias-" bench/bench.conf | head -n 1 | awk '{print $4}')
    conv2="$OUT/converged-$scene-seed8.exr"
    if [ ! -f "$conv" ]; then
        echo "converged.sh: $scene: reference at $CONV_SPP spp (crop $crop)" >&2
        "$BUILD/penumbra" render "$SHARED/scenes/$scene/$scene-matte.pbrt" --crop "$crop" --integrator reference \
            --spp "$CONV_SPP" --seed 7 --threads "$THREADS" --quiet -o "$conv" --stats "$OUT/converged-$scene.json"
    fi
    if [ ! -f "$conv2" ]; then
        echo "converged.sh: $scene: its second seed, for its own noise" >&2
        "$BUILD/penumbra" render "$SHARED/scenes/$scene/$scene-matte.pbrt" --crop "$crop" --integrator reference \
            --spp "$CONV_SPP" --seed 8 --threads "$THREADS" --quiet -o "$conv2"
    fi
    "$BUILD/penumbra" diff "$conv" "$conv2" > "$OUT/converged-$scene-noise.txt"
    echo "converged.sh: $scene: seed 7 against seed 8: $(grep relMSE "$OUT/converged-$scene-noise.txt")" >&2
    grep "^eq-$key-" bench/bench.conf | { if [ "${BVH:-0}" = 1 ]; then cat; else grep -v -- '-bvh-'; fi; } |
        awk -v ref="$conv" '{ $3 = ref; print }' >> "$CONF"
done
[ "${REFS_ONLY:-0}" = 1 ] && exit 0
"$BUILD/penumbra_bench" --config "$CONF" --runs "$RUNS" --threads "$THREADS" --out "$OUT"
