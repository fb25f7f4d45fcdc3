#!/bin/sh
# relocation.sh — confidence relocation (Guo 1998, §6.2) against uniformly spread confidence, on the
# crops of the prog-* bench cases. A converged image (the `full` driver at GT_SPP eye rays per work
# pixel, another seed) is the benchmark image, as the paper's 256 super-samples per pixel. Against
# it, at about equal time:
#   - uniform confidence: the `full` driver (every work pixel) at UNIFORM_SPP eye rays;
#   - relocated confidence: `dcm` stopped at 6% of the work pixels at RELOC_SPP eye rays, so each
#     evaluated pixel is 16x more confident for about the same number of rays.
# Time is the render's own (stats render_seconds: primary buffer, evaluation and reconstruction),
# without parsing and BVH building.
#
#   bench/progressive/relocation.sh [BUILD_DIR] [OUT_DIR]    (defaults: build, bench/results/relocation)
#
# Environment: PN_SHARED (default ../shared), THREADS (default 2), GT_SPP (default 256),
# UNIFORM_SPP (default "4 16"), RELOC_SPP (default "64 256").
set -eu
BUILD=${1:-build}
OUT=${2:-bench/results/relocation}
SHARED=${PN_SHARED:-../shared}
THREADS=${THREADS:-2}
GT_SPP=${GT_SPP:-256}
UNIFORM_SPP=${UNIFORM_SPP:-4 16}
RELOC_SPP=${RELOC_SPP:-64 256}
P="$BUILD/penumbra"
mkdir -p "$OUT"
TABLE="$OUT/relocation.md"
printf '| scene | image | eye rays per evaluated work pixel | evaluated work pixels %% | render s | rel L1 | rel L2 | relMSE |\n|---|---|---|---|---|---|---|---|\n' > "$TABLE"

seconds() { sed -n 's/.*"render_seconds": *\([0-9.e+-]*\).*/\1/p' "$1" | head -n 1 | awk '{printf "%.2f", $1}'; }

# row KEY LABEL SPP PCT IMAGE JSON
row() {
    m=$("$P" diff "$OUT/$1-truth.pfm" "$5")
    l1=$(echo "$m" | sed -n 's/^rel L1 *//p')
    l2=$(echo "$m" | sed -n 's/^rel L2 *//p')
    rm=$(echo "$m" | sed -n 's/^relMSE *\([0-9.e+-]*\).*/\1/p')
    printf '| %s | %s | %s | %s | %s | %s | %s | %s |\n' "$1" "$2" "$3" "$4" "$(seconds "$6")" "$l1" "$l2" "$rm" >> "$TABLE"
}

# scene KEY FILE RESOLUTION
scene() {
    key=$1 file=$2 res=$3
    A="--resolution $res --crop 0.3,0.7,0.3,0.7 --shadow-rays 4 --threads $THREADS --quiet"
    if [ ! -f "$OUT/$key-truth.pfm" ]; then
        "$P" render "$SHARED/scenes/$file" $A --driver full --spp "$GT_SPP" --seed 7 -o "$OUT/$key-truth.pfm" \
            --stats "$OUT/$key-truth.json" 2>/dev/null
    fi
    for s in $UNIFORM_SPP; do
        "$P" render "$SHARED/scenes/$file" $A --driver full --spp "$s" --seed 0 -o "$OUT/$key-full-$s.pfm" \
            --stats "$OUT/$key-full-$s.json" 2>/dev/null
        row "$key" "uniform (full)" "$s" 100 "$OUT/$key-full-$s.pfm" "$OUT/$key-full-$s.json"
    done
    for s in $RELOC_SPP; do
        "$P" render "$SHARED/scenes/$file" $A --driver dcm --stop-at 6 --spp "$s" --seed 0 -o "$OUT/$key-dcm-$s.pfm" \
            --stats "$OUT/$key-dcm-$s.json" 2>/dev/null
        row "$key" "relocated (dcm, 6%)" "$s" 6 "$OUT/$key-dcm-$s.pfm" "$OUT/$key-dcm-$s.json"
    done
}

scene staircase staircase-832/staircase-832-matte.pbrt 288x512
scene hall-many hall-many/hall-many-matte.pbrt 384x384
scene bathroom bathroom-72/bathroom-72-matte.pbrt 384x384
cat "$TABLE"
