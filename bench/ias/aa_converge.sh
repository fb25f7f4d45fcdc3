#!/bin/sh
# aa_converge.sh — does ias's threshold mode converge as T falls? (issue 21, ias's convergence
# test). Per scene: a converged fixed-spp `reference` render of the crop (REF_SPP, seeds 1000 and
# 1001, the second measuring the first's noise), then `ias` at each threshold with each
# ias-aa-threshold value (AAS; 0: the paper's fixed aa-rays eye rays), over SEEDS seeds, each timed
# as user + system CPU seconds and compared with the converged render (relMSE, rel L1, mean
# luminance).
#
#   bench/ias/aa_converge.sh [BUILD_DIR] [OUT_DIR]
#
# Environment: PN_SHARED (../shared), THREADS (1), CROP (0.45,0.55,0.45,0.55), REF_SPP (2048),
# THRESHOLDS ("0.01 0.0025 0.001"), AAS ("0 0.01"), SEEDS ("0 1"), IAS_EXTRA (more ias options),
# SCENES (folder/file, default the four many-light scenes' matte variants). One line per render.
set -eu
BUILD=${1:-build}
OUT=${2:-bench/results/aa_converge}
SHARED=${PN_SHARED:-../shared}
THREADS=${THREADS:-1}
CROP=${CROP:-0.45,0.55,0.45,0.55}
REF_SPP=${REF_SPP:-2048}
THRESHOLDS=${THRESHOLDS:-0.01 0.0025 0.001}
AAS=${AAS:-0 0.01}
SEEDS=${SEEDS:-0 1}
IAS_EXTRA=${IAS_EXTRA:-}
EXTRA= # lib.sh adds EXTRA to every render, the converged ones too
SCENES=${SCENES:-hall-many/hall-many-matte staircase-832/staircase-832-matte bathroom-72/bathroom-72-matte living-env-138/living-env-138-matte}
mkdir -p "$OUT"
PN="$BUILD/penumbra"

. "$(dirname "$0")/lib.sh"

for s in $SCENES; do
    scene="$SHARED/scenes/$s.pbrt"
    name=$(basename "$s")
    ref="$OUT/$name-ref$REF_SPP-s1000.exr"
    ref2="$OUT/$name-ref$REF_SPP-s1001.exr"
    [ -f "$ref" ] || pn_render_cpu "$ref" --spp "$REF_SPP" --seed 1000 > /dev/null
    [ -f "$ref2" ] || pn_render_cpu "$ref2" --spp "$REF_SPP" --seed 1001 > /dev/null
    {
        pn_diff_line "ref-seed2" 0 "$ref2"
        for t in $THRESHOLDS; do
            for seed in $SEEDS; do
                for aa in $AAS; do # alternated within each (threshold, seed)
                    cpu=$(pn_render_cpu "$OUT/tmp.exr" --integrator ias --threshold "$t" --ias-aa-threshold "$aa" \
                        --seed "$seed" $IAS_EXTRA)
                    pn_diff_line "aa=$aa:t=$t:s=$seed" "$cpu" "$OUT/tmp.exr"
                done
            done
        done
    } | tee "$OUT/$name.txt"
done
rm -f "$OUT/tmp.exr" "$OUT/tmp.exr.time"
