#!/bin/sh
# test_mpi.sh — renders across 3 MPI ranks (docs/distributed.md) on the demo scene are the
# one-process render byte for byte for reference, ias, lightcuts, illumcut (with a tile-size,
# given to both) and contour; a progressive driver is refused; a rank that cannot load the scene
# ends the job with one message naming it and a non-zero exit; a checkpointed MPI render resumed
# in one process gives the same image.
#   usage: test_mpi.sh PENUMBRA_BINARY SOURCE_DIR MPIEXEC
set -u
P=$1
S=$2/scenes/demo/demo.pbrt
MPIEXEC=${3:-mpirun}
t=$(mktemp -d) || exit 2
trap 'rm -rf "$t"' EXIT
root=""
[ "$(id -u)" -eq 0 ] && root="--allow-run-as-root"
M="$MPIEXEC $root --oversubscribe -np 3"
fail=0
check() { if eval "$2"; then echo "ok: $1"; else echo "FAILED: $1"; fail=1; fi; }
A="--resolution 64x48 --threads 1 --aov shadow_rays,normal --quiet"

for case in "reference --spp 2" "ias --threshold 0.05" "lightcuts --vpls 500" \
    "illumcut --vpls 500 --tile-size 16" "contour --tile-size 16"; do
    name=${case%% *}
    opts=${case#* }
    "$P" render "$S" $A --integrator $name $opts -o "$t/$name-1.exr" || exit 1
    $M "$P" render "$S" $A --integrator $name $opts -o "$t/$name-3.exr" --stats "$t/$name.json" > "$t/out" 2>&1
    check "$name: 3 ranks exit 0" "[ $? -eq 0 ]"
    check "$name: 3 ranks give the one-process image" "cmp -s '$t/$name-1.exr' '$t/$name-3.exr'"
    check "$name: the statistics name 3 ranks and their busy time" \
        "grep -q '\"ranks\": *3' '$t/$name.json' && grep -q rank_busy_seconds '$t/$name.json'"
done

$M "$P" render "$S" --resolution 32x24 --quiet --driver dcm -o "$t/dcm.exr" > "$t/out" 2>&1
check "dcm under MPI is refused with a reason" "[ $? -ne 0 ] && grep -q 'does not run over MPI ranks' '$t/out'"

# Rank 2 is given a scene it cannot read; the job ends with one message naming it.
$M sh -c 'if [ "$OMPI_COMM_WORLD_RANK" = 2 ]; then s=$0.missing; else s=$0; fi; exec "$1" render "$s" --quiet \
    --resolution 32x24 --spp 1 -o "$2"' "$S" "$P" "$t/fail.exr" > "$t/out" 2>&1
code=$?
check "a rank failing to load: non-zero exit" "[ $code -ne 0 ]"
check "a rank failing to load: one message naming rank 2" \
    "[ \$(grep -c 'rank 2 of 3' '$t/out') -eq 1 ] && [ ! -e '$t/fail.exr' ]"

# A checkpoint written by 3 ranks resumes in one process (same command otherwise).
$M "$P" render "$S" $A --spp 2 --checkpoint "$t/m.ckpt" -o "$t/m3.exr" > /dev/null 2>&1
"$P" render "$S" $A --spp 2 --checkpoint "$t/m.ckpt" -o "$t/m1.exr" --stats "$t/m1.json"
check "a 3-rank checkpoint, resumed in one process, gives the same image" \
    "cmp -s '$t/m3.exr' '$t/m1.exr' && cmp -s '$t/m1.exr' '$t/reference-1.exr' && grep -q '\"tiles_resumed\": *[1-9]' '$t/m1.json'"
exit $fail
