#!/bin/sh
# bitident.sh — spectral mode's counterpart of bench/bitident.sh: every integrator and driver in
# spectral mode on small crops of staircase-832-matte (hundreds of coloured lights, textures) and
# bathroom-72-matte, rendered by two binaries and compared with cmp (the EXR bytes, AOVs included).
#   usage: bench/spectral/bitident.sh OLD_BINARY NEW_BINARY [OUT_DIR]
# Prints one line per case (same / DIFFERENT / FAILED) and exits non-zero on any difference.
set -u
OLD=$1
NEW=$2
OUT=${3:-/tmp/penumbra-bitident-spectral}
HERE=$(cd "$(dirname "$0")/../.." && pwd)
S=$HERE/../shared/scenes
mkdir -p "$OUT"
STAIR=$S/staircase-832/staircase-832-matte.pbrt
BATH=$S/bathroom-72/bathroom-72-matte.pbrt
C="--crop 0.45,0.55,0.45,0.52 --threads 2 --quiet --spectral"
bad=0
run() { # name scene args...
    name=$1; scene=$2; shift 2
    "$OLD" render "$scene" -o "$OUT/$name.old.exr" "$@" >/dev/null 2>"$OUT/$name.old.err"; a=$?
    "$NEW" render "$scene" -o "$OUT/$name.new.exr" "$@" >/dev/null 2>"$OUT/$name.new.err"; b=$?
    if [ $a -ne 0 ] || [ $b -ne 0 ]; then echo "FAILED     $name (exit $a / $b)"; bad=1
    elif cmp -s "$OUT/$name.old.exr" "$OUT/$name.new.exr"; then echo "same       $name"
    else echo "DIFFERENT  $name"; bad=1; fi
}
# shellcheck disable=SC2086
{
run reference   "$STAIR" $C --integrator reference --spp 4 --aov all
run ias         "$STAIR" $C --integrator ias
run contour     "$STAIR" $C --integrator contour --spp 4
run contour-mc  "$STAIR" $C --integrator contour-mc --spp 4
run vpl         "$STAIR" $C --integrator vpl --vpls 2000 --aov all
run lightcuts   "$STAIR" $C --integrator lightcuts --vpls 4000
run illumcut    "$STAIR" $C --integrator illumcut --vpls 4000
run dcm         "$STAIR" $C --driver dcm --spp 4
run bath-ref    "$BATH"  $C --integrator reference --spp 4
run bath-ias    "$BATH"  $C --integrator ias
run bath-lc     "$BATH"  $C --integrator lightcuts --vpls 4000
}
exit $bad
