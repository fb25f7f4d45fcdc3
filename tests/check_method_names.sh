#!/bin/sh
# check_method_names.sh — no integrator or driver name is spelled in src/ outside the method table
# (src/integrators/registry.c) and the method's own files, so that nothing chooses a method by
# comparing its name (a strcmp on "illumcut" in render.c or the CLI fails this test).
#
# The names come from `penumbra methods` (nothing is listed here by hand). A method's own files
# are those whose name starts with the method's first word, hyphens read as underscores
# (contour-mc: contour*.c; vpl: vpl*.c). A line whose literal is an ordinary word and not a method
# (diff's "reference" image) says so with the comment marker "not-a-method-name".
#   usage: check_method_names.sh SOURCE_DIR PENUMBRA_BINARY
set -u
SRC=$1/src
BIN=$2
names=$("$BIN" methods | sed -n 's/^\([a-z][a-z0-9-]*\) (\(integrator\|driver\)):.*/\1/p')
[ -n "$names" ] || { echo "no methods listed by '$BIN methods'"; exit 1; }
count=0 bad=0
for name in $names; do
    count=$((count + 1))
    stem=$(printf '%s' "$name" | sed 's/-.*//; s/-/_/g')
    hits=$(grep -rn --include='*.c' --include='*.h' -F "\"$name\"" "$SRC" | grep -v 'not-a-method-name' |
        while IFS=: read -r file line rest; do
            base=$(basename "$file")
            case "$base" in
            registry.c | "$stem".* | "$stem"_*) ;;
            *) printf '%s:%s: the method name "%s" outside the method table: %s\n' "$file" "$line" "$name" "$rest" ;;
            esac
        done)
    if [ -n "$hits" ]; then
        printf '%s\n' "$hits"
        bad=1
    fi
done
[ "$count" -ge 12 ] || { echo "only $count methods listed"; bad=1; }
[ $bad -eq 0 ] && echo "ok: $count method names appear only in the table and their own files"
exit $bad
