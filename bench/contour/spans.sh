#!/bin/sh
# spans.sh — §5 spans of the contour integrator: shadow rays per viewing ray and average 8-bit
# difference from a 1024-shadow-ray reference for several maximum span lengths (--contour-span),
# on the lower half of cornell-contour (the crop of table1.sh), one eye ray per pixel, the
# paper's 9 first-level samples and 5 dichotomy steps unless EXTRA says otherwise.
#
#   bench/contour/spans.sh [BUILD_DIR] [OUT_DIR] [SPAN...]   (defaults: build, bench/results/contour-spans, 8 64)
#
# Environment: PN_SHARED (default ../shared), THREADS (default 2), RES (default 512),
# CROP (default 0.25,0.75,0.5,1), EXTRA (more render options), LD_LIBRARY_PATH to run an older
# build's binary against its own library.
set -eu
BUILD=${1:-build}
OUT=${2:-bench/results/contour-spans}
shift 2 2>/dev/null || shift $#
SPANS=${*:-8 64}
SHARED=${PN_SHARED:-../shared}
THREADS=${THREADS:-2}
RES=${RES:-512}
CROP=${CROP:-0.25,0.75,0.5,1}
EXTRA=${EXTRA:-}
P="$BUILD/penumbra"
M="$OUT/contour_metrics"
SCENE="$SHARED/scenes/cornell-contour/cornell-contour.pbrt"
mkdir -p "$OUT"
LIB=$(cd "${METRICS_BUILD:-$BUILD}" && pwd)
cc -O2 -std=c11 -Iinclude bench/contour/contour_metrics.c -L"$LIB" -lpenumbra -Wl,-rpath,"$LIB" -lm -o "$M"
if [ ! -f "$OUT/ref.pfm" ]; then
    "$P" render "$SCENE" --resolution "${RES}x${RES}" --crop "$CROP" --spp 1 --shadow-rays 1024 \
        --threads "$THREADS" --quiet -o "$OUT/ref.pfm" 2>/dev/null
fi
printf '| span | settings | shadow rays / viewing ray | avg. diff. (8-bit) | max diff. | time (s) |\n|---|---|---|---|---|---|\n'
for span in $SPANS; do
    name="span$span"
    start=$(date +%s.%N)
    # shellcheck disable=SC2086
    "$P" render "$SCENE" --resolution "${RES}x${RES}" --crop "$CROP" --spp 1 --shadow-rays 4 \
        --threads "$THREADS" --quiet --integrator contour --contour-span "$span" $EXTRA \
        -o "$OUT/$name.pfm" --png "$OUT/$name.png" --stats "$OUT/$name.json" 2>/dev/null
    end=$(date +%s.%N)
    rays=$(sed -n 's/.*"contour_shadow_rays_per_viewing_ray": *\([0-9.e+-]*\).*/\1/p' "$OUT/$name.json")
    metrics=$("$M" "$OUT/ref.pfm" "$OUT/$name.pfm" --error-png "$OUT/$name.err16.png")
    avg=$(echo "$metrics" | sed 's/.*"avg_diff_8bit": \([0-9.]*\).*/\1/')
    max=$(echo "$metrics" | sed 's/.*"max_diff_8bit": \([0-9]*\).*/\1/')
    t=$(echo "$end $start" | awk '{printf "%.2f", $1 - $2}')
    printf '| %s | `%s` | %.1f | %s | %s | %s |\n' "$span" "--contour-span $span $EXTRA" "$rays" "$avg" "$max" "$t"
done
