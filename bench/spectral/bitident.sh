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
C="--crop 0.45,0.55,0.45,0.52 --threads 2 --quiet --spectral" # no spaces in paths
# One case a line: name, scene, arguments.
cases() {
    cat <<CASES
reference   $STAIR $C --integrator reference --spp 4 --aov all
ias         $STAIR $C --integrator ias
contour     $STAIR $C --integrator contour --spp 4
contour-mc  $STAIR $C --integrator contour-mc --spp 4
vpl         $STAIR $C --integrator vpl --vpls 2000 --aov all
lightcuts   $STAIR $C --integrator lightcuts --vpls 4000
illumcut    $STAIR $C --integrator illumcut --vpls 4000
dcm         $STAIR $C --driver dcm --spp 4
bath-ref    $BATH $C --integrator reference --spp 4
bath-ias    $BATH $C --integrator ias
bath-lc     $BATH $C --integrator lightcuts --vpls 4000
CASES
}
bad=0
cases | while read -r name scene args; do
    for which in old new; do
        bin=$OLD; [ $which = new ] && bin=$NEW
        # shellcheck disable=SC2086
        "$bin" render "$scene" -o "$OUT/$name.$which.exr" $args >/dev/null 2>"$OUT/$name.$which.err" ||
            echo "failed" >"$OUT/$name.$which.status"
    done
    if [ -e "$OUT/$name.old.status" ] || [ -e "$OUT/$name.new.status" ]; then
        echo "FAILED     $name"
    elif cmp -s "$OUT/$name.old.exr" "$OUT/$name.new.exr"; then
        echo "same       $name"
    else
        echo "DIFFERENT  $name"
    fi
    rm -f "$OUT/$name.old.status" "$OUT/$name.new.status"
done | tee "$OUT/summary.txt"
grep -qv '^same' "$OUT/summary.txt" && bad=1
exit $bad
