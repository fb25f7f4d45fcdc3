#!/bin/sh
# bitident.sh — checks that two penumbra binaries render bit-identical images: every integrator
# and driver on small crops of the shared scenes and the demo scene, compared with cmp (the EXR
# bytes, all AOV layers included).
#   usage: bench/bitident.sh OLD_BINARY NEW_BINARY [OUT_DIR]
# Prints one line per case (same / DIFFERENT / FAILED) and exits non-zero on any difference.
set -u
OLD=$1
NEW=$2
OUT=${3:-/tmp/penumbra-bitident}
HERE=$(cd "$(dirname "$0")/.." && pwd)
S=$HERE/../shared/scenes
mkdir -p "$OUT"
CORNELL=$S/cornell-box/cornell-box-matte.pbrt
CONTOUR=$S/cornell-contour/cornell-contour-matte.pbrt
HALL=$S/hall-many/hall-many-matte.pbrt
BATH=$S/bathroom-72/bathroom-72-matte.pbrt
DEMO=$HERE/scenes/demo/demo.pbrt
SMALL="--resolution 128x128 --threads 2 --quiet"
CROP="--crop 0.4,0.6,0.4,0.6 --threads 2 --quiet"
bad=0
run() { # name scene args...
  name=$1; scene=$2; shift 2
  "$OLD" render "$scene" -o "$OUT/$name.old.exr" "$@" >/dev/null 2>"$OUT/$name.old.err"; a=$?
  "$NEW" render "$scene" -o "$OUT/$name.new.exr" "$@" >/dev/null 2>"$OUT/$name.new.err"; b=$?
  if [ $a -ne 0 ] || [ $b -ne 0 ]; then echo "FAILED     $name (exit $a / $b)"; bad=1
  elif cmp -s "$OUT/$name.old.exr" "$OUT/$name.new.exr"; then echo "same       $name"
  else echo "DIFFERENT  $name"; bad=1; fi
}
run ref-spp-irr        "$CORNELL" $SMALL --spp 4 --aov all
run ref-spp-bvh        "$HALL"    $CROP --spp 4 --light-sampler bvh
run ref-thr-irr        "$HALL"    $CROP --threshold 0.05 --aov eye_rays,shadow_rays,relative_variance
run ref-thr-bvh        "$BATH"    $CROP --threshold 0.05 --light-sampler bvh --shadow-rays 2
run ias                "$HALL"    $CROP --integrator ias --threshold 0.05 --aov passes,clusters,visible_fraction
run ias-block16        "$CORNELL" $SMALL --integrator ias --threshold 0.05 --block-size 16 --cluster-solid-angle 0.05
run contour            "$CONTOUR" $SMALL --integrator contour --aov gradient
run contour-opts       "$CONTOUR" $SMALL --integrator contour --contour-grid 5 --contour-off spans,scouts --spp 2
run contour-mc         "$CONTOUR" $SMALL --integrator contour-mc --mc-threshold 0.004
run vpl                "$CORNELL" $SMALL --integrator vpl --vpls 2000
run lightcuts          "$CORNELL" $SMALL --integrator lightcuts --vpls 5000 --error 0.02 --aov bound_evaluations,cut_size
run illumcut           "$CORNELL" $SMALL --integrator illumcut --vpls 5000 --aov phase1,cut_size
run illumcut-sampling  "$CORNELL" $SMALL --integrator illumcut --vpls 5000 --visibility sampling
run dcm                "$CORNELL" --resolution 64x64 --threads 2 --quiet --driver dcm --spp 2 --aov sampling_pattern,block_map
run painter            "$CORNELL" --resolution 64x64 --threads 2 --quiet --driver painter --spp 2 --stop-at 20
run uniform            "$CORNELL" --resolution 64x64 --threads 2 --quiet --driver uniform --spp 2 --work-scale 2
run full               "$CORNELL" --resolution 64x64 --threads 2 --quiet --driver full --spp 2
run dcm-ias            "$CORNELL" --resolution 64x64 --threads 2 --quiet --driver full --integrator ias --threshold 0.05
run demo               "$DEMO"    $SMALL --spp 4
run demo-ias           "$DEMO"    $SMALL --integrator ias --threshold 0.05
run ref-default      "$CORNELL" $SMALL
run ref-thr-paper    "$HALL"    $CROP --threshold 0.05 --adaptive-rule paper
run vpl-scene-depth   "$CORNELL" $SMALL --integrator vpl --vpls 2000 --spp 1
exit $bad
