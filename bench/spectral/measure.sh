#!/bin/sh
# measure.sh — spectral mode against RGB mode (issue 20), docs/spectral.md's tables:
#  1. accuracy: on the shared matte scenes, a central crop rendered by the reference integrator in
#     RGB and in spectral mode, against pbrt-v4's reference image of the same pixels: the ratio of
#     mean luminance and of each channel's mean (pn_crop_means);
#  2. cost: the CPU time (user + sys) of each integrator and progressive driver in both modes on
#     one scene, methods and modes alternated, median of 3, minus the CPU time of the same command
#     on a one-pixel window (scene loading and preprocessing, the same in both modes).
# The scenes' own film resolution (that of the references); veach-ajar-matte's centre is dark in
# direct light, so its crop is the lit corner. usage:
#   [METHODS="m1|m2"] bench/spectral/measure.sh [BUILD_DIR] [OUT_DIR] [accuracy|cost|all]
set -eu
here=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$here/build}
out=${2:-/tmp/penumbra-spectral}
what=${3:-all}
shared=$here/../shared
mkdir -p "$out"
pn=$build/penumbra
CROP=0.35,0.65,0.35,0.65
SPP=16

if [ "$what" != cost ]; then
echo "## accuracy: reference integrator, crop $CROP, $SPP spp, image / pbrt-v4 (luminance R G B)"
echo "| scene | RGB mode | spectral mode |"
echo "|---|---|---|"
for s in bathroom-72/bathroom-72-matte cornell-box/cornell-box-matte cornell-contour/cornell-contour-matte \
         hall-many/hall-many-matte living-env-138/living-env-138-matte living-room/living-room-matte \
         staircase/staircase-matte staircase-832/staircase-832-matte staircase2/staircase2-matte \
         veach-ajar/veach-ajar-matte; do
    name=${s#*/}
    ref=$shared/reference/$name.exr
    crop=$CROP
    [ "$name" = veach-ajar-matte ] && crop=0.8,1,0.6,1
    line="| $name |"
    for mode in rgb spectral; do
        flag=""; [ $mode = spectral ] && flag=--spectral
        # shellcheck disable=SC2086
        "$pn" render "$shared/scenes/$s.pbrt" -o "$out/$name.$mode.exr" --crop $crop \
            --spp $SPP --threads 2 --quiet $flag 2>/dev/null
        x0=${crop%%,*}; r=${crop#*,}; x1=${r%%,*}; r=${r#*,}; y0=${r%%,*}; y1=${r#*,}
        line="$line $("$build/pn_crop_means" "$ref" "$out/$name.$mode.exr" "$x0" "$x1" "$y0" "$y1") |"
    done
    echo "$line"
done
fi
[ "$what" = accuracy ] && exit 0

# CPU seconds (user + sys) of one command.
cpu() {
    /usr/bin/time -f "%U %S" -o "$out/time" "$@" >/dev/null 2>&1 || { echo "failed: $*" >&2; exit 1; }
    awk '{ printf "%.3f\n", $1 + $2 }' "$out/time"
}
median3() { printf '%s\n%s\n%s\n' "$1" "$2" "$3" | sort -g | sed -n 2p; }

SCENE=$shared/scenes/staircase-832/staircase-832-matte.pbrt
TCROP=0.4,0.6,0.4,0.6
TINY=0.5,0.504,0.5,0.503
echo
echo "## cost: staircase-832-matte (288x512), crop $TCROP, CPU seconds of the render (median of 3, minus a one-pixel window)"
echo "| method | RGB (s) | spectral (s) | spectral / RGB |"
echo "|---|---|---|---|"
# METHODS (optional): a subset, "|"-separated, e.g. METHODS="ias|lightcuts --vpls 20000".
all_methods="reference|ias|contour --spp 16|contour-mc --spp 16|vpl --vpls 4000|lightcuts --vpls 20000|\
illumcut --vpls 20000|reference --driver dcm|reference --driver painter|reference --driver uniform"
IFS='|'
# shellcheck disable=SC2086
set -- ${METHODS:-$all_methods}
unset IFS
for m in "$@"; do
    integ=${m%% *}; rest=""; [ "$integ" != "$m" ] && rest=${m#* }
    base="$pn render $SCENE -o $out/t.exr --threads 2 --quiet --integrator $integ $rest"
    for k in 1 2 3; do
        # shellcheck disable=SC2086
        eval "r$k=\$(cpu $base --crop $TCROP)"
        # shellcheck disable=SC2086
        eval "s$k=\$(cpu $base --crop $TCROP --spectral)"
    done
    # shellcheck disable=SC2086
    e_r=$(cpu $base --crop $TINY); e_s=$(cpu $base --crop $TINY --spectral)
    # shellcheck disable=SC2154
    r=$(median3 "$r1" "$r2" "$r3"); s=$(median3 "$s1" "$s2" "$s3")
    awk -v m="$m" -v r="$r" -v s="$s" -v er="$e_r" -v es="$e_s" \
        'BEGIN { a = r - er; b = s - es; printf "| %s | %.2f | %.2f | %.2f |\n", m, a, b, b / a }'
done
