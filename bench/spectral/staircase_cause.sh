#!/bin/sh
# staircase_cause.sh — is staircase-832-matte's brightness against pbrt-v4 the RGB product?
# For each light colour of the scene (flame bulbs 2200 K, a warm and a cool globe, the LED strip,
# a wall light) and each reflectance it lights (the wood, wallpaper and painting textures, the
# grey paints), prints the luminance and channel ratios of penumbra's RGB product to pbrt-v4's
# spectral product (sigmoid-polynomial upsampling of both, D65-based illuminant, CIE 1931).
# usage: bench/spectral/staircase_cause.sh [BUILD_DIR]
set -eu
here=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$here/build}
tex=$here/../shared/scenes/staircase/textures
for light in "182.428 57.1111 5.12356" "112.996 49.0627 12.292" "99.9588 52.212 19.4839" \
             "0.0350926 0.0169853 0.00542137" "0.715355 0.325534 0.0908519"; do
    # shellcheck disable=SC2086
    "$build/pn_rgb_product" $light "$tex/WoodFloor.tga" "$tex/WoodPanel.tga" "$tex/Wood.tga" \
        "$tex/Wallpaper.tga" "$tex/Painting1.tga" 0.578596,0.578596,0.578596 0.5,0.5,0.5 0.35,0.17,0.07
    echo
done
