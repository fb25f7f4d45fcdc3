#!/bin/sh
# check_layers.sh — the include rules between src/ modules (ARCHITECTURE.md's layering), so that a
# cycle or a reach into another module's internals fails CTest instead of creeping back in.
#
# Rules (an `#include "module/..."` line in a .c or .h file under src/):
#   1. src/shade/   includes nothing from lights/  (lights/ builds on shade/: VPLs bounce off
#                   BSDFs and the light tree uses shade/bounds.h; pn_vpl_kind lives in bounds.h).
#   2. src/lights/  includes none of the scene parser's internals (scene/parser_internal.h,
#                   params.h, tokenizer.h, build.h, ply.h) and nothing from driver/ or integrators/;
#                   and it calls no pn_scene_warn (warnings go through core/warn.h's pn_warn).
#   3. src/scene/   includes nothing from driver/ or integrators/, and lights/ only from the two
#                   files that hand parsed lights to the light builder (lightdefs.c: light
#                   definitions and their kinds; scene_load.c: builds the light records after
#                   parsing). Those two are the known remaining scene -> lights edges.
#   4. src/integrators/ includes nothing from driver/, and traces no eye ray itself: it calls none
#                   of render/'s eye tracers (pn_camera_ray, pn_camera_filter_sample,
#                   pn_pixel_eye_sample, pn_trace_eye_path*, pn_eye_point_trace, pn_eye_hits_trace);
#                   its eye samples come from the batch (render/batch.h), traced by the driver.
#   usage: check_layers.sh SOURCE_DIR          check SOURCE_DIR/src
#          check_layers.sh --self-test         check that each rule catches a planted violation
set -u

# Prints "file:line: why" for every include in $1/src that breaks a rule; exit status 1 if any.
check_tree() {
    src=$1/src
    out=$(
        grep -rn --include='*.c' --include='*.h' '^[[:space:]]*#[[:space:]]*include[[:space:]]*"lights/' \
            "$src/shade" 2>/dev/null | sed 's/$/  <- shade\/ must not include lights\//'
        grep -rnE --include='*.c' --include='*.h' \
            '^[[:space:]]*#[[:space:]]*include[[:space:]]*"(scene/(parser_internal|params|tokenizer|build|ply)\.h|driver/|integrators/)' \
            "$src/lights" 2>/dev/null | sed 's/$/  <- lights\/ must not include parser internals, driver\/ or integrators\//'
        grep -rnw --include='*.c' --include='*.h' 'pn_scene_warn' "$src/lights" 2>/dev/null |
            sed 's/$/  <- lights\/ reports warnings with pn_warn (core\/warn.h), not the parser/'
        grep -rnE --include='*.c' --include='*.h' '^[[:space:]]*#[[:space:]]*include[[:space:]]*"(driver|integrators)/' \
            "$src/scene" 2>/dev/null | sed 's/$/  <- scene\/ must not include driver\/ or integrators\//'
        grep -rn --include='*.c' --include='*.h' '^[[:space:]]*#[[:space:]]*include[[:space:]]*"lights/' "$src/scene" 2>/dev/null |
            grep -v "^$src/scene/\(lightdefs\|scene_load\)\.c:" |
            sed 's/$/  <- scene\/ includes lights\/ only in lightdefs.c and scene_load.c/'
        grep -rn --include='*.c' --include='*.h' '^[[:space:]]*#[[:space:]]*include[[:space:]]*"driver/' \
            "$src/integrators" 2>/dev/null | sed 's/$/  <- integrators\/ must not include driver\//'
        grep -rnE --include='*.c' \
            '\b(pn_camera_ray|pn_camera_filter_sample|pn_pixel_eye_sample|pn_trace_eye_path(_spectral)?|pn_eye_point_trace|pn_eye_hits_trace)[[:space:]]*\(' \
            "$src/integrators" 2>/dev/null |
            sed 's/$/  <- integrators\/ read eye samples from the batch (render\/batch.h), the driver traces them/'
    )
    if [ -n "$out" ]; then
        printf '%s\n' "$out"
        return 1
    fi
    return 0
}

if [ "${1:-}" = "--self-test" ]; then
    tmp=$(mktemp -d) || exit 1
    trap 'rm -rf "$tmp"' EXIT
    fail=0
    # Each case: a file to plant and a line for it; the check must reject every one of them,
    # and accept the allowed edges.
    plant() { # dir file line expect(0 ok / 1 rejected)
        rm -rf "$tmp/src"
        mkdir -p "$tmp/src/shade" "$tmp/src/lights" "$tmp/src/scene" "$tmp/src/integrators"
        printf '%s\n' "$3" >"$tmp/src/$1/$2"
        check_tree "$tmp" >/dev/null
        got=$?
        if [ "$got" -ne "$4" ]; then
            echo "self-test: src/$1/$2 with '$3': expected $4, got $got"
            fail=1
        fi
    }
    plant shade bounds.c '#include "lights/vpl.h"' 1
    plant shade bsdf.h '  #  include "lights/lights.h"' 1
    plant shade bsdf.c '#include "shade/bounds.h"' 0
    plant lights lights.c '#include "scene/parser_internal.h"' 1
    plant lights vpl.c '#include "scene/params.h"' 1
    plant lights vpl.c '#include "driver/progress.h"' 1
    plant lights light_tree.h '#include "integrators/integrator.h"' 1
    plant lights lights.c '    pn_scene_warn(scene, "x");' 1
    plant lights lights.c '#include "scene/scene.h"' 0
    plant lights lights.c '#include "shade/bsdf.h"' 0
    plant scene parser.c '#include "driver/render_job.h"' 1
    plant scene params.c '#include "integrators/registry.h"' 1
    plant scene parser.c '#include "lights/lights.h"' 1
    plant scene scene_load.c '#include "lights/lights.h"' 0
    plant scene lightdefs.c '#include "lights/lights.h"' 0
    plant integrators ias.c '#include "driver/render_job.h"' 1
    plant integrators ias.c '#include "render/batch.h"' 0
    plant integrators ias.c '    pn_trace_eye_path(job, o, d, u, &path);' 1
    plant integrators vpl_common.c '        pn_eye_point_trace(job, x, y, s, &pt);' 1
    plant integrators contour.c 'pn_camera_ray(&job->camera, rx, ry, 0.5f, 0.5f, &o, &d);' 1
    plant integrators reference.c '    h = pn_batch_eye_hits(job, batch, pi, seq, i, n, buf);' 0
    [ "$fail" -eq 0 ] && echo "check_layers self-test: every rule catches its planted violation"
    exit "$fail"
fi

[ $# -eq 1 ] || { echo "usage: check_layers.sh SOURCE_DIR | --self-test"; exit 2; }
[ -d "$1/src/shade" ] && [ -d "$1/src/lights" ] && [ -d "$1/src/scene" ] || { echo "no src/{shade,lights,scene} in $1"; exit 2; }
if check_tree "$1"; then
    echo "check_layers: shade/, lights/, scene/ and integrators/ keep their rules"
    exit 0
fi
exit 1
