#!/bin/sh
# staircase_texture.sh — staircase-matte's central crop against pbrt-v4 (issue 20), the texture
# cause: the crop (0.35-0.65 in x and y) at 64 spp, seeds 0 and 1, RGB and spectral mode, with
# one or more penumbra binaries (e.g. a build before image-texture pyramids and one after), and
# the crop's top band (rows 0.35-0.42: the wall panel, where the pyramid level matters most) and
# the rest (0.42-0.65). Each cell: image / pbrt-v4 for the mean luminance, then R, G, B.
# usage: bench/spectral/staircase_texture.sh [OUT_DIR] BINARY...   (run with nice -n 10)
set -eu
here=$(cd "$(dirname "$0")/../.." && pwd)
out=${1:-/tmp/penumbra-staircase-texture}
shift || true
[ $# -gt 0 ] || set -- "$here/build/penumbra"
mkdir -p "$out"
scene=$here/../shared/scenes/staircase/staircase-matte.pbrt
ref=$here/../shared/reference/staircase-matte.exr
means=$here/build/pn_crop_means
echo "| binary | window | mode | seed 0 | seed 1 |"
echo "|---|---|---|---|---|"
k=0
for bin in "$@"; do
    k=$((k + 1))
    for win in "0.35 0.65 0.35 0.65" "0.35 0.65 0.35 0.42" "0.35 0.65 0.42 0.65"; do
        # shellcheck disable=SC2086
        set -- $win
        for mode in rgb spectral; do
            flag=""
            [ $mode = spectral ] && flag=--spectral
            line="| $k | $1-$2 x $3-$4 | $mode |"
            for seed in 0 1; do
                img=$out/b$k.$mode.$seed.$3.exr
                # shellcheck disable=SC2086
                "$bin" render "$scene" -o "$img" --crop "$1,$2,$3,$4" --spp 64 --seed $seed --threads 2 \
                    --quiet $flag 2>/dev/null
                line="$line $("$means" "$ref" "$img" "$1" "$2" "$3" "$4") |"
            done
            echo "$line"
        done
    done
done
