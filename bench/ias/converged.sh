#!/bin/sh
# converged.sh — the eq-* comparison of `ias` against `reference` (issue 3) measured against a
# converged penumbra render of each crop window instead of the pbrt-v4 image, so that equal-relMSE
# ratios are not bent by the floor the pbrt images set (spectral against RGB rendering, the pbrt
# image's own noise). The converged crop: `reference` at --threshold CONV_T with seed 7 (the eq-*
# cases use seed 0); penumbra_bench compares a reference of the crop window's size as it is.
#
#   bench/ias/converged.sh [BUILD_DIR] [OUT_DIR]    (defaults: build, bench/results/ias-converged)
#
# Environment: PN_SHARED (default ../shared), THREADS (default 2), CONV_T (default 0.0002),
# SCENES (default "hall-many:hall staircase-832:stair"), RUNS (default 1), BVH (1: also the light
# BVH cases).
set -eu
BUILD=${1:-build}
OUT=${2:-bench/results/ias-converged}
SHARED=${PN_SHARED:-../shared}
THREADS=${THREADS:-2}
CONV_T=${CONV_T:-0.0002}
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
    if [ ! -f "$conv" ]; then
        echo "converged.sh: $scene: reference at threshold $CONV_T (crop $crop)" >&2
        "$BUILD/penumbra" render "$SHARED/scenes/$scene/$scene-matte.pbrt" --crop "$crop" --integrator reference \
            --threshold "$CONV_T" --seed 7 --threads "$THREADS" --quiet -o "$conv" --stats "$OUT/converged-$scene.json"
    fi
    grep "^eq-$key-" bench/bench.conf | { if [ "${BVH:-0}" = 1 ]; then cat; else grep -v -- '-bvh-'; fi; } |
        awk -v ref="$conv" '{ $3 = ref; print }' >> "$CONF"
done
"$BUILD/penumbra_bench" --config "$CONF" --runs "$RUNS" --threads "$THREADS" --out "$OUT"
