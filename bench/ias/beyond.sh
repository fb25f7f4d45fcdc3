#!/bin/sh
# beyond.sh — issue 15's bench: CPU time to equal relMSE of `ias` (default and paper variants)
# against `reference` and `reference --light-sampler bvh`, on the four many-light scenes (matte and
# original) and on generated scenes of 10^3 .. 10^6 emitting triangles (bench/ias/gen_many.py,
# fixed seeds), each against a converged fixed-spp render of the same crop window (cached under
# OUT). One thread per render, at low priority; see bench/ias/beyond.py for the method.
#
#   bench/ias/beyond.sh [BUILD_DIR] [OUT_DIR]     (defaults: build, bench/out/beyond)
#
# Times are the render phase's CPU seconds (the scene's load subtracted; beyond.py).
#
# Environment: PN_SHARED (../shared), CROP (0.375,0.625,0.375,0.625: the shared scenes' window,
# 128x128 pixels of a 512-pixel-wide image, so that per-render constants stay small),
# GEN_CROP (0.3,0.7,0.55,0.95: the generated scenes' window, floor and spheres), GEN ("1000 10000
# 100000 1000000": emitter counts; empty for none; their converged renders use the light BVH),
# SKIP (SCENE:METHOD pairs left out; default at 10^6 emitters the paper variant, whose per-block
# arrays would need ~12 GB, and reference's O(N)-per-point PDF, minutes per render), SHARED_SCENES (default the eight below; empty
# for none), CONV_SPP (1024), RUNS (3), METHODS ("ref bvh ias-paper ias"; NAME-main runs MAIN_BIN; ias-ratio-MODE: ias with --ias-ratio MODE; ias-mis, ias-mis-on, ias-nomis: ias with --ias-mis glossy, on, off; ias-imp, ias-large: ias with --ias-cluster-pick importance, large; ias-capK, ias-capK-imp, ias-capK-large for K = 128, 256: ias with --ias-cut-max K and the power, importance or large pick), IAS_T,
# MAIN_BIN (beyond.py), NICE (15: the priority).
set -eu
BUILD=${1:-build}
OUT=${2:-bench/out/beyond}
SHARED=${PN_SHARED:-../shared}
CROP=${CROP:-0.375,0.625,0.375,0.625}
GEN_CROP=${GEN_CROP:-0.3,0.7,0.55,0.95}
GEN=${GEN-1000 10000 100000 1000000}
SHARED_SCENES=${SHARED_SCENES-hall-many/hall-many-matte hall-many/hall-many staircase-832/staircase-832-matte staircase-832/staircase-832 bathroom-72/bathroom-72-matte bathroom-72/bathroom-72 living-env-138/living-env-138-matte living-env-138/living-env-138}
mkdir -p "$OUT/gen"
SCENES=""
for s in $SHARED_SCENES; do
    SCENES="$SCENES $(basename "$s"):$SHARED/scenes/$s.pbrt:$CROP"
done
for n in $GEN; do
    [ -f "$OUT/gen/many-$n.pbrt" ] || python3 "$(dirname "$0")/gen_many.py" "$n" "$OUT/gen"
    SCENES="$SCENES many-$n:$OUT/gen/many-$n.pbrt:$GEN_CROP:bvh"
done
SKIP=${SKIP-many-1000000:ias-paper many-1000000:ref} SCENES=$SCENES exec nice -n "${NICE:-15}" python3 "$(dirname "$0")/beyond.py" "$BUILD" "$OUT"
