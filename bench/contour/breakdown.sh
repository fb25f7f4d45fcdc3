#!/bin/sh
# breakdown.sh — where the contour integrator's shadow rays go on the cornell-contour bench crop
# (the crop of table1.sh and spans.sh): renders with --contour-trace FILE (contour_render.c writes
# one line per counted pixel) and tabulates rays per pixel by phase (pattern check, first level,
# side dichotomy, validity diagonals, case-4 centre, subdivision, restart pass) and the average
# and signed 8-bit difference for each pixel class (every traced ray visible / every one hidden /
# both), with why pixels were integrated (bench/contour/ray_breakdown.c).
#
#   bench/contour/breakdown.sh [BUILD_DIR] [OUT_DIR] [render options...]
#       e.g. bench/contour/breakdown.sh build bench/results/contour-rays --contour-span 64
#
# Environment: PN_SHARED (default ../shared), THREADS (default 2), RES (film side, default 512; the
# paper renders 800). The 1024-ray reference is rendered once into OUT_DIR/ref.pfm (the same as
# spans.sh's at the same RES).
set -eu
BUILD=${1:-build}
OUT=${2:-bench/results/contour-rays}
shift 2 2>/dev/null || shift $#
SHARED=${PN_SHARED:-../shared}
THREADS=${THREADS:-2}
RES=${RES:-512}
P="$BUILD/penumbra"
SCENE="$SHARED/scenes/cornell-contour/cornell-contour.pbrt"
mkdir -p "$OUT"
LIB=$(cd "$BUILD" && pwd)
cc -O2 -std=c11 -Iinclude bench/contour/ray_breakdown.c -L"$LIB" -lpenumbra -Wl,-rpath,"$LIB" -lm -o "$OUT/ray_breakdown"
cc -O2 -std=c11 -Iinclude bench/contour/contour_metrics.c -L"$LIB" -lpenumbra -Wl,-rpath,"$LIB" -lm -o "$OUT/contour_metrics"
COMMON="--resolution ${RES}x${RES} --crop 0.25,0.75,0.5,1 --spp 1 --threads $THREADS --quiet"
if [ ! -f "$OUT/ref.pfm" ]; then
    # shellcheck disable=SC2086
    "$P" render "$SCENE" $COMMON --shadow-rays 1024 -o "$OUT/ref.pfm" 2>/dev/null
fi
# shellcheck disable=SC2086
"$P" render "$SCENE" $COMMON --shadow-rays 4 --integrator contour --contour-trace "$OUT/trace.txt" "$@" \
    -o "$OUT/image.pfm" --stats "$OUT/image.json" 2>/dev/null
rays=$(sed -n 's/.*"contour_shadow_rays_per_viewing_ray": *\([0-9.e+-]*\).*/\1/p' "$OUT/image.json")
echo "options: $*; shadow rays / viewing ray: $rays; $("$OUT/contour_metrics" "$OUT/ref.pfm" "$OUT/image.pfm")"
echo
# The crop window starts at pixel (RES/4, RES/2) of the RESxRES image.
"$OUT/ray_breakdown" "$OUT/trace.txt" "$OUT/ref.pfm" "$OUT/image.pfm" $((RES / 4)) $((RES / 2))
