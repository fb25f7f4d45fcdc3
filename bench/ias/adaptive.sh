#!/bin/sh
# adaptive.sh — measures the adaptive (threshold) mode of `reference` against fixed --spp on the
# bench scenes (docs/adaptive-sampling.md): per scene and crop, a converged fixed-spp render (REF_SPP
# eye rays, seed 1000) whose own noise is measured by a second seed (1001), then fixed --spp renders
# and threshold renders with each --adaptive-rule, all with seed 0, each timed as user + system CPU
# seconds and compared with the converged render (relMSE, rel L1, mean luminance).
#
#   bench/ias/adaptive.sh [BUILD_DIR] [OUT_DIR]     (defaults: build, bench/results/adaptive)
#
# Environment: PN_SHARED (default ../shared), THREADS (2), CROP (0.45,0.55,0.45,0.55), REF_SPP
# (2048), SPPS ("16 32 64 128 256"), THRESHOLDS ("0.01 0.003 0.001 0.0003"), RULES ("cross paper"),
# EXTRA (more render options, e.g. "--light-sampler bvh"), SCENES (default: the six scenes of
# bench/bench.conf, as folder/file). Prints one line per render to stdout and OUT_DIR/NAME.txt;
# bench/ias/adaptive_table.py turns those into the equal-relMSE speed-up table.
set -eu
BUILD=${1:-build}
OUT=${2:-bench/results/adaptive}
SHARED=${PN_SHARED:-../shared}
THREADS=${THREADS:-2}
CROP=${CROP:-0.45,0.55,0.45,0.55}
REF_SPP=${REF_SPP:-2048}
SPPS=${SPPS:-16 32 64 128 256}
THRESHOLDS=${THRESHOLDS:-0.01 0.003 0.001 0.0003}
RULES=${RULES:-cross paper}
EXTRA=${EXTRA:-}
SCENES=${SCENES:-cornell-box/cornell-box-matte cornell-contour/cornell-contour-matte hall-many/hall-many-matte staircase-832/staircase-832-matte living-env-138/living-env-138-matte bathroom-72/bathroom-72-matte}
mkdir -p "$OUT"
PN="$BUILD/penumbra"

. "$(dirname "$0")/lib.sh"

for s in $SCENES; do
    scene="$SHARED/scenes/$s.pbrt"
    name=$(basename "$s")
    ref="$OUT/$name-ref$REF_SPP-s1000.exr"
    ref2="$OUT/$name-ref$REF_SPP-s1001.exr"
    [ -f "$ref" ] || pn_render_cpu "$ref" --spp "$REF_SPP" --seed 1000 > /dev/null
    [ -f "$ref2" ] || pn_render_cpu "$ref2" --spp "$REF_SPP" --seed 1001 > /dev/null
    {
        pn_diff_line "ref-seed2" 0 "$ref2"
        for n in $SPPS; do
            cpu=$(pn_render_cpu "$OUT/tmp.exr" --spp "$n" --seed 0)
            pn_diff_line "spp=$n" "$cpu" "$OUT/tmp.exr"
        done
        for rule in $RULES; do
            for t in $THRESHOLDS; do
                cpu=$(pn_render_cpu "$OUT/tmp.exr" --threshold "$t" --adaptive-rule "$rule" --seed 0)
                pn_diff_line "$rule:t=$t" "$cpu" "$OUT/tmp.exr"
            done
        done
    } | tee "$OUT/$name.txt"
done
rm -f "$OUT/tmp.exr" "$OUT/tmp.exr.time"
