#!/bin/sh
# check_method_docs.sh — the options tables of docs/methods/*.md against the method table.
#   usage: check_method_docs.sh SOURCE_DIR PENUMBRA_BINARY
#
# The method table (src/integrators/registry.c, printed by `penumbra methods --markdown`) is the
# truth. For every method it lists, the page that documents it must list exactly the options the
# table declares for it, no more and no fewer:
#   - a method's page is docs/methods/NAME.md; contour-mc is on contour.md, and the progressive
#     drivers (full, dcm, painter, uniform) on progressive.md;
#   - the options listed are the first-column flags (| `--flag ...` |) of the tables in the page's
#     "## Options" section; where that section has a "### `NAME`" subsection for the method, only
#     that subsection counts;
#   - `--spp` and `--threshold` are the common sampling settings: a page lists them exactly where
#     the table's sampling column says the method takes them;
#   - the tiles driver has no page: its options must be in the README's "## Common options" table
#     (which lists the settings of every method besides), or on a page that mentions them.
# Exits 1 and names each difference.
#
#   check_method_docs.sh --self-test SOURCE_DIR PENUMBRA_BINARY
# checks the check: on a copy of the pages it must pass unchanged, fail when vpl.md lists a flag
# vpl does not take (--error), and fail when lightcuts.md misses one it takes (--vpl-clamp).
set -u
if [ "${1-}" = --self-test ]; then
    st=$(mktemp -d) || exit 2
    trap 'rm -rf "$st"' EXIT
    mkdir -p "$st/src/docs" && cp -R "$2/docs/methods" "$st/src/docs/" && cp "$2/README.md" "$st/src/" || exit 2
    sh "$0" "$st/src" "$3" > "$st/out" || { echo "self-test: unchanged copy fails:"; cat "$st/out"; exit 1; }
    m=$st/src/docs/methods
    cp "$m/vpl.md" "$st/vpl.md"
    sed '/^| `--vpls N`/p; s/^| `--vpls N`/| `--error E`/' "$st/vpl.md" | awk '!(/^\| `--error E`/ && seen++)' > "$m/vpl.md"
    if sh "$0" "$st/src" "$3" > "$st/out"; then echo "self-test: a foreign --error on vpl.md passed"; exit 1; fi
    grep -q 'vpl: docs/methods/vpl.md lists --error, which vpl does not take' "$st/out" ||
        { echo "self-test: foreign flag not named:"; cat "$st/out"; exit 1; }
    cp "$st/vpl.md" "$m/vpl.md"
    grep -v '^| `--vpl-clamp F`' "$m/lightcuts.md" > "$st/lc.md" && cp "$st/lc.md" "$m/lightcuts.md"
    if sh "$0" "$st/src" "$3" > "$st/out"; then echo "self-test: lightcuts.md without --vpl-clamp passed"; exit 1; fi
    grep -q 'lightcuts: --vpl-clamp missing from docs/methods/lightcuts.md' "$st/out" ||
        { echo "self-test: missing flag not named:"; cat "$st/out"; exit 1; }
    echo "self-test: passes unchanged, fails on a foreign and on a missing flag"
    exit 0
fi
SRC=$1
BIN=$2
tmp=$(mktemp -d) || exit 2
trap 'rm -rf "$tmp"' EXIT
"$BIN" methods --markdown > "$tmp/table.md" || { echo "penumbra methods --markdown failed"; exit 1; }

# method name, its options (space-separated, with --), and its sampling flags, from the table.
awk -F'|' '/^\| `[a-z-]*` \| (integrator|driver) \|/ {
    name = $2; gsub(/[ `]/, "", name)
    sampling = $6; opts = $7
    gsub(/`/, "", opts); gsub(/,/, " ", opts)
    n = split(opts, o, " "); list = ""
    for (i = 1; i <= n; i++) if (o[i] != "-") list = list " --" o[i]
    if (sampling ~ /spp/) list = list " --spp"
    if (sampling ~ /threshold/) list = list " --threshold"
    print name "|" list
}' "$tmp/table.md" > "$tmp/methods"
[ -s "$tmp/methods" ] || { echo "no method found in penumbra methods --markdown"; exit 1; }

# The flags of the "## Options" section of PAGE (subsection NAME when the page has one for it).
page_flags() { # page name
    awk -v name="$2" '
        /^## / { in_opts = ($0 ~ /^## Options/); sub_name = ""; next }
        in_opts && /^### / { sub_name = $0; gsub(/[#` ]/, "", sub_name); next }
        in_opts && /^\| `--/ { split($0, c, "|"); f = c[2]; gsub(/`/, "", f); split(f, w, " ");
                               print sub_name "|" w[1] }
    ' "$1" > "$tmp/rows"
    if grep -q "^$2|" "$tmp/rows"; then grep "^$2|" "$tmp/rows"; else grep "^|" "$tmp/rows"; fi |
        cut -d'|' -f2 | sort -u
}

bad=0
while IFS='|' read -r name opts; do
    case $name in
    contour-mc) page=$SRC/docs/methods/contour.md ;;
    full | dcm | painter | uniform) page=$SRC/docs/methods/progressive.md ;;
    tiles) page="" ;;
    *) page=$SRC/docs/methods/$name.md ;;
    esac
    printf '%s\n' $opts | sed '/^$/d' | sort -u > "$tmp/want"
    if [ -z "$page" ]; then
        awk '/^## /{p = ($0 ~ /^## Common options/); next} p && /^\| `--/ {split($0,c,"|"); f=c[2];
             gsub(/`/,"",f); split(f,w," "); print w[1]}' "$SRC/README.md" | sort -u > "$tmp/have"
        for f in $(cat "$tmp/want"); do
            if ! grep -qx -- "$f" "$tmp/have" && ! grep -rqF -- "\`$f" "$SRC/docs/methods"; then
                echo "$name: $f is documented nowhere (README common options or a method page)"; bad=1
            fi
        done
        continue
    fi
    if [ ! -f "$page" ]; then echo "$name: no page $page"; bad=1; continue; fi
    page_flags "$page" "$name" > "$tmp/have"
    for f in $(comm -23 "$tmp/want" "$tmp/have"); do echo "$name: $f missing from ${page#$SRC/}"; bad=1; done
    for f in $(comm -13 "$tmp/want" "$tmp/have"); do echo "$name: ${page#$SRC/} lists $f, which $name does not take"; bad=1; done
done < "$tmp/methods"
[ $bad -eq 0 ] && echo "every method page lists exactly its options"
exit $bad
