# lib.sh — shell functions shared by bench/ias's scripts (sourced, not run).
#
# pn_render_cpu OUT.exr options...: renders $scene (crop $CROP, $THREADS threads, options $EXTRA
#   then the arguments) with $PN into OUT.exr and prints the render's CPU seconds (user + system).
# pn_diff_line TAG CPU IMAGE: one line of IMAGE's metrics against the converged render $ref:
#   "NAME TAG cpu S relmse R rel_l1 L dmean D%" (bench/ias/adaptive_table.py parses it).

pn_render_cpu() {
    out=$1
    shift
    /usr/bin/time -f "%U %S" -o "$out.time" "$PN" render "$scene" --crop "$CROP" --threads "$THREADS" --quiet \
        -o "$out" ${EXTRA:-} "$@" 2>/dev/null
    awk '{ printf "%.3f", $1 + $2 }' "$out.time"
}

pn_diff_line() {
    "$PN" diff "$ref" "$3" --json | awk -v tag="$1" -v cpu="$2" -v name="$name" '
        /"relmse"/ { r = $2 } /"rel_l1"/ { l = $2 }
        /"mean_luminance_reference"/ { mr = $2 } /"mean_luminance_image"/ { mi = $2 }
        END { gsub(",", "", r); gsub(",", "", l); gsub(",", "", mr); gsub(",", "", mi);
              printf "%-36s %-22s cpu %8.3f relmse %.4e rel_l1 %.5f dmean %+.4f%%\n", name, tag, cpu, r, l,
                     100 * (mi / mr - 1) }'
}
