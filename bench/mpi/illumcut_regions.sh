#!/bin/sh
# bench/mpi/illumcut_regions.sh — what splitting illumcut into regions costs (issue 16): illumcut
# builds one point tree over the window it renders, so a render split into --tile-size N regions
# (one tree each; the same in one process as under MPI or in --piece parts) is another estimate.
# On cornell-box-matte at its 512x512 film, 1 thread, this renders the whole window and regions
# of 256, 128 and 64 pixels (then the whole window again, for the noise), and prints the time, illumcut's pairs and shadow rays, and relMSE
# against pbrt-v4's reference and against the whole-window image.
#   usage: bench/mpi/illumcut_regions.sh [OUT_DIR]   (env: VPLS, default 20000)
set -u
HERE=$(cd "$(dirname "$0")/../.." && pwd)
P=${PENUMBRA:-$HERE/build/penumbra}
SCENE=$HERE/../shared/scenes/cornell-box/cornell-box-matte.pbrt
REF=$HERE/../shared/reference/cornell-box-matte.exr
OUT=${1:-$HERE/bench/results/mpi}
VPLS=${VPLS:-20000}
mkdir -p "$OUT"
stat_of() { sed -n "s/^ *\"$2\": *\([0-9.e+-]*\).*/\1/p" "$1" | head -1; }
relmse() { "$P" diff "$1" "$2" | sed -n 's/^relMSE *\([0-9.e+-]*\).*/\1/p'; }
echo "| regions | render s | CPU s | shadow rays | pairs | relMSE vs pbrt-v4 | relMSE vs whole window |"
echo "|---|---|---|---|---|---|---|"
for t in 0 256 128 64 0; do
    /usr/bin/time -f "%U" -o "$OUT/cpu" "$P" render "$SCENE" --integrator illumcut --vpls "$VPLS" --threads 1 \
        --tile-size $t --quiet -o "$OUT/ic-$t.exr" --stats "$OUT/ic-$t.json" || exit 1
    js=$OUT/ic-$t.json
    label=$t
    [ $t -eq 0 ] && label="whole window"
    echo "| $label | $(stat_of "$js" render_seconds) | $(cat "$OUT/cpu") | $(stat_of "$js" shadow_rays) |" \
        "$(stat_of "$js" illumcut_pairs) |" \
        "$(relmse "$OUT/ic-$t.exr" "$REF") | $(relmse "$OUT/ic-$t.exr" "$OUT/ic-0.exr") |"
done
