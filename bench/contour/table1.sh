#!/bin/sh
# table1.sh — Vedel 1993, Table 1, on penumbra's scenes: a 1024-shadow-ray reference, `contour` at
# the paper's settings (9 first-level samples, 5 dichotomy steps) and tuned, and adaptive Monte
# Carlo (`contour-mc`, Kok & Jansen 1992) once at about contour's number of rays and once tuned to
# its quality. One eye ray per pixel, as in the paper. For each run: shadow rays per viewing ray
# (viewing rays that cast any towards the rectangle lights), the average absolute difference from
# the reference in 8-bit display values, relMSE, render time; images, error images x16 and
# close-ups of penumbrae go to OUT.
#
#   bench/contour/table1.sh [BUILD_DIR] [OUT_DIR]      (defaults: build, bench/results/contour)
#
# Environment: PN_SHARED (default ../shared), THREADS (default 2), RES (film side, default 512,
# the scenes' own; the paper renders 800: RES=800, same crops, close-up scaled).
set -eu
BUILD=${1:-build}
OUT=${2:-bench/results/contour}
SHARED=${PN_SHARED:-../shared}
THREADS=${THREADS:-2}
RES=${RES:-512}
P="$BUILD/penumbra"
M="$BUILD/contour_metrics"
mkdir -p "$OUT"
cc -O2 -std=c11 -Iinclude bench/contour/contour_metrics.c -L"$BUILD" -lpenumbra -Wl,-rpath,"$(cd "$BUILD" && pwd)" -lm -o "$M"

TABLE="$OUT/table1.md"
printf '| scene | method | settings | shadow rays / viewing ray | avg. diff. (8-bit) | max diff. | relMSE | time (s) |\n|---|---|---|---|---|---|---|---|\n' > "$TABLE"

# run NAME SCENE CROP EXTRA... : renders one image and appends a table row.
run() {
    name=$1 scene=$2 crop=$3 label=$4
    shift 4
    start=$(date +%s.%N)
    "$P" render "$SHARED/scenes/$scene" --resolution "${RES}x${RES}" --crop "$crop" --spp 1 --threads "$THREADS" --quiet \
        -o "$OUT/$name.pfm" --png "$OUT/$name.png" --stats "$OUT/$name.json" "$@" 2>/dev/null
    end=$(date +%s.%N)
    rays=$(sed -n 's/.*"contour_shadow_rays_per_viewing_ray": *\([0-9.e+-]*\).*/\1/p' "$OUT/$name.json")
    [ -n "$rays" ] || rays=1024
    ref="$OUT/${name%%.*}.ref.pfm"
    metrics=$("$M" "$ref" "$OUT/$name.pfm" --error-png "$OUT/$name.err16.png" $CLOSEUPS)
    avg=$(echo "$metrics" | sed 's/.*"avg_diff_8bit": \([0-9.]*\).*/\1/')
    max=$(echo "$metrics" | sed 's/.*"max_diff_8bit": \([0-9]*\).*/\1/')
    rel=$(echo "$metrics" | sed 's/.*"relmse": \([0-9.e+-]*\).*/\1/')
    t=$(echo "$end $start" | awk '{printf "%.2f", $1 - $2}')
    printf '| %s | %s | `%s` | %.1f | %s | %s | %s | %s |\n' "${name%%.*}" "$label" "$*" "$rays" "$avg" "$max" "$rel" "$t" >> "$TABLE"
}

# scene KEY SCENE CROP OTHER_LIGHT_RAYS CLOSEUP
scene() {
    key=$1 file=$2 crop=$3 other=$4
    CLOSEUPS=""
    "$P" render "$SHARED/scenes/$file" --resolution "${RES}x${RES}" --crop "$crop" --spp 1 --shadow-rays 1024 --threads "$THREADS" --quiet \
        -o "$OUT/$key.ref.pfm" --png "$OUT/$key.ref.png" 2>/dev/null
    if [ -n "$5" ]; then CLOSEUPS="--closeup $5,$OUT/$key.ref.closeup.png"; "$M" "$OUT/$key.ref.pfm" "$OUT/$key.ref.pfm" $CLOSEUPS >/dev/null; fi
    printf '| %s | reference | `--shadow-rays 1024` | 1024.0 | - | - | - | - |\n' "$key" >> "$TABLE"
    for spec in "contour-paper;contour, the paper's 9 samples and 5 steps;--integrator contour" \
                "contour-g5s4;contour tuned;--integrator contour --contour-grid 5 --contour-steps 4" \
                "contour-g7s3;contour tuned;--integrator contour --contour-grid 7 --contour-steps 3 --contour-off adaptive" \
                "contour-g6s3;contour tuned, fixed 6x6 first level, span 64;--integrator contour --contour-grid 6 --contour-steps 3 --contour-off adaptive --contour-span 64" \
                "contour-fixed64;contour, the paper's 9 samples and 5 steps, fixed density, span 64;--integrator contour --contour-off adaptive --contour-span 64" \
                "mc-g2;adaptive MC, its coarsest grid (fewest rays);--integrator contour-mc --contour-grid 2 --mc-threshold 0.02" \
                "mc-same-rays;adaptive MC at about contour-paper's rays;--integrator contour-mc --contour-grid 3 --mc-threshold 0.02" \
                "mc-g9;adaptive MC;--integrator contour-mc --contour-grid 9 --mc-threshold 0.02" \
                "mc-g10;adaptive MC at about contour-g6s3's quality;--integrator contour-mc --contour-grid 10 --mc-threshold 0.02" \
                "mc-g13;adaptive MC tuned to contour-g7s3's quality;--integrator contour-mc --contour-grid 13 --mc-threshold 0.02" \
                ${EXTRA:+"$EXTRA"}; do
        n=${spec%%;*}; rest=${spec#*;}; label=${rest%%;*}; args=${rest#*;}
        if [ -n "$5" ]; then CLOSEUPS="--closeup $5,$OUT/$key.$n.closeup.png"; fi
        # shellcheck disable=SC2086
        run "$key.$n" "$file" "$crop" "$label" $args --shadow-rays "$other"
    done
}

# cornell-contour: the lower half (floor, blocks, penumbrae of the sphere and the killeroo).
EXTRA="mc-g17;adaptive MC, finer;--integrator contour-mc --contour-grid 17 --mc-threshold 0.02"
C=$((176 * RES / 512)),$((176 * RES / 512)),$((64 * RES / 512)),$((64 * RES / 512))
scene cornell-contour cornell-contour/cornell-contour.pbrt 0.25,0.75,0.5,1 4 "$C"
EXTRA=""
# The many-light scenes: small crops; their point and disk lights (hall-many) go to the
# reference estimator with as many rays as the reference uses.
scene hall-many hall-many/hall-many-matte.pbrt 0.45,0.55,0.45,0.55 1024 ""
scene bathroom-72 bathroom-72/bathroom-72-matte.pbrt 0.45,0.55,0.45,0.55 4 ""
cat "$TABLE"
