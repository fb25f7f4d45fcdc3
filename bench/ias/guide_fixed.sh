#!/bin/sh
# fx.sh LABEL PASSES SEED [extra args...]  (env passes through) -> relMSE, shadow rays, cpu
L=$1; P=$2; S=$3; shift 3
B=${BIN:-/work/wt-guide2/build/penumbra}
SC=/work/shared/scenes/bathroom-72/bathroom-72-matte.pbrt
o=/tmp/g2/fx-$L-$P-$S.exr
/usr/bin/time -f "%U %S" -o /tmp/g2/fx-$L.time nice -n 10 $B render $SC --integrator ias --threads 1 --seed $S --crop 0.375,0.625,0.375,0.625 --quiet --threshold 1e-7 --max-passes $P --ias-aa-threshold 0 --stats /tmp/g2/fx-$L.stats -o $o "$@" 2>/dev/null
r=$($B diff /tmp/g2/converged-bathroom-72-matte-512-seed7.exr $o --json | python3 -c 'import json,sys;print("%.5f"%json.load(sys.stdin)["relmse"])')
rays=$(python3 -c 'import json,sys;d=json.load(open(sys.argv[1]));print(d)' /tmp/g2/fx-$L.stats 2>/dev/null | head -c 0)
echo "$L P=$P seed=$S relmse=$r cpu=$(cat /tmp/g2/fx-$L.time)"
