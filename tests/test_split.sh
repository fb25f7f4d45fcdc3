#!/bin/sh
# test_split.sh — the CLI side of split, merged and resumed renders (docs/distributed.md):
# `penumbra merge` of four crop EXRs is the full render byte for byte and refuses overlapping,
# mismatched and incomplete parts with exit 3; a render with --checkpoint killed (SIGKILL) after
# some tiles and run again with the same command gives the uninterrupted image; a checkpoint of
# another seed is refused with exit 3.
#   usage: test_split.sh PENUMBRA_BINARY SOURCE_DIR
set -u
P=$1
S=$2/scenes/demo/demo.pbrt
t=$(mktemp -d) || exit 2
trap 'rm -rf "$t"' EXIT
fail=0
check() { if eval "$2"; then echo "ok: $1"; else echo "FAILED: $1"; fail=1; fi; }
A="--resolution 96x64 --spp 2 --threads 1 --aov shadow_rays,normal,depth --quiet"

"$P" render "$S" $A -o "$t/full.exr" --stats "$t/full.json" || exit 1
i=0
for c in 0,0.4,0,0.5 0.4,1,0,0.5 0,0.6,0.5,1 0.6,1,0.5,1; do
    i=$((i + 1))
    "$P" render "$S" $A --crop $c -o "$t/p$i.exr" --stats "$t/p$i.json" || exit 1
done
"$P" merge "$t/p1.exr" "$t/p2.exr" "$t/p3.exr" "$t/p4.exr" "$t"/p*.json -o "$t/merged.exr" --stats "$t/merged.json"
check "merge of 4 crops exits 0" "[ $? -eq 0 ]"
check "merge of 4 crops is the full render byte for byte" "cmp -s '$t/full.exr' '$t/merged.exr'"
check "merged statistics sum the parts' eye rays" \
    "grep -q '\"eye_rays\": *12288' '$t/merged.json'"
# The merged statistics combine by the table's rules (pn_stat_info.merge) into the whole render's:
# sums, maxima, the whole size and pixel-weighted means agree with one render of the window.
json_num() { sed -n "s/^ *\"$1\": *\([-0-9.e+]*\),*\$/\1/p" "$2" | head -n 1; }
for k in shadow_rays eye_rays_per_pixel_max shadow_rays_per_pixel_max width height; do
    check "merged $k is the whole render's" "[ -n \"\$(json_num $k '$t/full.json')\" ] && [ \"\$(json_num $k '$t/merged.json')\" = \"\$(json_num $k '$t/full.json')\" ]"
done
check "merged shadow_rays_per_pixel_mean is the whole render's (pixel-weighted)" \
    "awk -v a=\"\$(json_num shadow_rays_per_pixel_mean '$t/merged.json')\" -v b=\"\$(json_num shadow_rays_per_pixel_mean '$t/full.json')\" \
        'BEGIN { d = a - b; exit !(b > 0 && d * d < 1e-18 * b * b) }'"
"$P" merge "$t/p1.exr" "$t/p1.exr" "$t/p2.exr" "$t/p3.exr" "$t/p4.exr" -o "$t/bad.exr" 2> "$t/err"
check "overlapping parts: exit 3" "[ $? -eq 3 ] && grep -q overlaps '$t/err' && [ ! -e '$t/bad.exr' ]"
"$P" merge "$t/p1.exr" "$t/p2.exr" "$t/p3.exr" -o "$t/bad.exr" 2> "$t/err"
check "a missing part: exit 3" "[ $? -eq 3 ] && grep -q 'do not cover' '$t/err'"
"$P" render "$S" --resolution 48x32 --spp 2 --quiet --crop 0,0.5,0,1 -o "$t/small.exr" || exit 1
"$P" merge "$t/p1.exr" "$t/small.exr" -o "$t/bad.exr" 2> "$t/err"
check "parts of another display window: exit 3" "[ $? -eq 3 ] && grep -q 'display windows' '$t/err'"
"$P" merge "$t/p1.exr" -o "$t/bad.png" 2> /dev/null
check "a non-EXR output: exit 2" "[ $? -eq 2 ]"

# Killed and resumed: a slower render (more tiles), SIGKILL once the checkpoint holds a few.
B="--resolution 160x120 --spp 8 --threads 1 --tile-size 16 --quiet"
"$P" render "$S" $B -o "$t/whole.exr" || exit 1
"$P" render "$S" $B --checkpoint "$t/run.ckpt" -o "$t/run.exr" &
pid=$!
n=0
while [ $n -lt 200 ]; do
    size=$(stat -c %s "$t/run.ckpt" 2> /dev/null || echo 0)
    [ "$size" -gt 100000 ] && break
    sleep 0.02
    n=$((n + 1))
done
kill -9 $pid 2> /dev/null
wait $pid 2> /dev/null
check "the killed render wrote no image" "[ ! -e '$t/run.exr' ]"
"$P" render "$S" $B --checkpoint "$t/run.ckpt" -o "$t/run.exr" --stats "$t/run.json"
check "the resumed render exits 0" "[ $? -eq 0 ]"
check "it resumed finished tiles" "grep -q '\"tiles_resumed\": *[1-9]' '$t/run.json'"
check "the resumed image is the uninterrupted one" "cmp -s '$t/whole.exr' '$t/run.exr'"
"$P" render "$S" $B --seed 5 --checkpoint "$t/run.ckpt" -o "$t/other.exr" 2> "$t/err"
check "another seed's checkpoint: exit 3, no image" \
    "[ $? -eq 3 ] && grep -q 'another render' '$t/err' && [ ! -e '$t/other.exr' ]"
exit $fail
