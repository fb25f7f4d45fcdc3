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

# render NAME OUT.exr options...: prints the CPU seconds of the render
render() {
    out=$1
    shift
    /usr/bin/time -f "%U %S" -o "$out.time" "$PN" render "$scene" --crop "$CROP" --threads "$THREADS" --quiet \
        -o "$out" $EXTRA "$@" 2>/dev/null
    awk '{ printf "%.3f", $1 + $2 }' "$out.time"
}

# line TAG CPU IMAGE: the metrics of IMAGE against the converged render
line() {
    "$PN" diff "$ref" "$3" --json | awk -v tag="$1" -v cpu="$2" -v name="$name" '
        /"relmse"/ { r = $2 } /"rel_l1"/ { l = $2 }
        /"mean_luminance_reference"/ { mr = $2 } /"mean_luminance_image"/ { mi = $2 }
        END { gsub(",", "", r); gsub(",", "", l); gsub(",", "", mr); gsub(",", "", mi);
              printf "%-36s %-14s cpu %8.3f relmse %.4e rel_l1 %.5f dmean %+.4f%%\n", name, tag, cpu, r, l,
                     100 * (mi / mr - 1) }'
}

for s in $SCENES; do
    scene="$SHARED/scenes/$s.pbrt"
    name=$(basename "$s")
    ref="$OUT/$name-ref$REF_SPP-s1000.exr"
    ref2="$OUT/$name-ref$REF_SPP-s1001.exr"
    [ -f "$ref" ] || render "$ref" --spp "$REF_SPP" --seed 1000 > /dev/null
    [ -f "$ref2" ] || render "$ref2" --spp "$REF_SPP" --seed 1001 > /dev/null
    {
        line "ref-seed2" 0 "$ref2"
        for n in $SPPS; do
            cpu=$(render "$OUT/tmp.exr" --spp "$n" --seed 0)
            line "spp=$n" "$cpu" "$OUT/tmp.exr"
        done
        for rule in $RULES; do
            for t in $THRESHOLDS; do
                cpu=$(render "$OUT/tmp.exr" --threshold "$t" --adaptive-rule "$rule" --seed 0)
                line "$rule:t=$t" "$cpu" "$OUT/tmp.exr"
            done
        done
    } | tee "$OUT/$name.txt"
done
rm -f "$OUT/tmp.exr" "$OUT/tmp.exr.time"
