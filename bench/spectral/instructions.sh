#!/bin/sh
# instructions.sh — spectral mode's cost as instruction counts (valgrind callgrind, one thread):
# robust where CPU seconds are not (a loaded machine moves them by ±20 % between identical runs).
# For each method: the instructions executed inside the integrator's render_batch function (and
# what it calls; loading, BVH, VPL tracing and the light tree are outside it and the same in both
# modes) on staircase-832-matte's window C, in RGB and in spectral mode, and their ratio. usage:
#   [CG_DIR=DIR] bench/spectral/instructions.sh PENUMBRA [METHOD...]  (default: ias, lightcuts, vpl)
# With CG_DIR the callgrind profiles are kept there (METHOD.rgb.cg, METHOD.spectral.cg) for
# callgrind_annotate.
set -eu
here=$(cd "$(dirname "$0")/../.." && pwd)
pn=$1
shift
[ $# -gt 0 ] || set -- "ias" "lightcuts --vpls 20000" "vpl --vpls 4000"
SCENE=$here/../shared/scenes/staircase-832/staircase-832-matte.pbrt
C=${CROP:-0.47,0.53,0.47,0.53}
ins() { # name args...
    f=/dev/null; [ -n "${CG_DIR:-}" ] && f=$CG_DIR/$1.cg
    shift
    valgrind --tool=callgrind --callgrind-out-file="$f" --toggle-collect='*_render_batch' "$pn" render "$SCENE" -o /tmp/pn-instr-$$.exr \
        --threads 1 --quiet "$@" 2>&1 | sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
echo "| method | RGB (M instructions) | spectral | spectral / RGB |"
echo "|---|---|---|---|"
for m in "$@"; do
    integ=${m%% *}; rest=""; [ "$integ" != "$m" ] && rest=${m#* }
    # shellcheck disable=SC2086
    r=$(ins $integ.rgb --integrator $integ $rest --crop $C)
    # shellcheck disable=SC2086
    s=$(ins $integ.spectral --integrator $integ $rest --crop $C --spectral)
    awk -v m="$m" -v r="$r" -v s="$s" \
        'BEGIN { a = r / 1e6; b = s / 1e6; printf "| %s | %.1f | %.1f | %.3f |\n", m, a, b, b / a }'
done
rm -f /tmp/pn-instr-$$.exr
