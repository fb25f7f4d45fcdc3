#!/bin/sh
# run.sh BUILD_DIR WORK_DIR — checks that an installed penumbra can be used from outside.
#
# 1. brings the library and the CLI of BUILD_DIR up to date and installs them into
#    WORK_DIR/prefix (a scratch prefix, rebuilt on every run);
# 2. checks that the installed CMake and pkg-config files point only into that prefix;
# 3. builds tests/install/consumer.c with the flags that pkg-config reads from penumbra.pc and
#    runs it with LD_LIBRARY_PATH pointing at the installed library; then compiles README.md's
#    library example (-Wall -Wextra -Werror) the same way and runs it on a tiny scene;
# 4. configures and builds tests/install/CMakeLists.txt, which calls find_package(penumbra),
#    against the prefix and runs that consumer too;
# 5. runs the installed `penumbra --version`.
#
# Tools are taken from $CMAKE, $CC and $PKG_CONFIG when set (the CTest registration passes the
# ones of the main build); $PN_CONSUMER_FLAGS is added to every consumer compile and link.
set -u

say() { printf 'test_install: %s\n' "$*"; }
fail() {
    printf 'test_install: FAILED: %s\n' "$*" >&2
    exit 1
}
# run LOG COMMAND...: runs a command with its output in LOG, shown only when the command fails.
run() {
    log=$1
    shift
    if ! "$@" >"$log" 2>&1; then
        cat "$log" >&2
        return 1
    fi
    return 0
}

if [ $# -ne 2 ]; then
    echo "usage: $0 BUILD_DIR WORK_DIR" >&2
    exit 2
fi

CMAKE=${CMAKE:-cmake}
CC=${CC:-cc}
PKG_CONFIG=${PKG_CONFIG:-pkg-config}
extra_flags=${PN_CONSUMER_FLAGS:-}

here=$(cd "$(dirname "$0")" && pwd) || fail "cannot find the folder of $0"
source_dir=$(cd "$here/../.." && pwd) || fail "cannot find the source tree"
[ -f "$1/CMakeCache.txt" ] || fail "$1 is not a configured CMake build folder"
build_dir=$(cd "$1" && pwd) || fail "cannot enter $1"
mkdir -p "$2" || fail "cannot create $2"
work=$(cd "$2" && pwd) || fail "cannot enter $2"

prefix=$work/prefix
missing_scene=$work/no-such-folder/no-such-scene.pbrt
# Only the folders this script owns are cleared, never WORK_DIR itself.
rm -rf "$prefix" "$work/pc" "$work/cmake" "$work/logs" || fail "cannot clear $work"
mkdir -p "$work/pc" "$work/logs" || fail "cannot create folders in $work"
[ ! -e "$missing_scene" ] || fail "$missing_scene exists but should not"

# --- 1. build and install ------------------------------------------------------------------
say "bringing penumbra and penumbra_cli up to date in $build_dir"
run "$work/logs/build.log" "$CMAKE" --build "$build_dir" --target penumbra penumbra_cli --parallel 2 \
    || fail "building the library and the CLI in $build_dir failed (output above)"

say "installing into $prefix"
run "$work/logs/install.log" "$CMAKE" --install "$build_dir" --prefix "$prefix" \
    || fail "cmake --install $build_dir --prefix $prefix failed (output above)"

# GNUInstallDirs may pick lib, lib64 or lib/<multiarch>: take the folder that holds penumbra.pc.
pc_file=$(find "$prefix" -path '*/pkgconfig/penumbra.pc' -type f | head -n 1)
[ -n "$pc_file" ] || fail "no pkgconfig/penumbra.pc anywhere under $prefix"
pc_dir=$(dirname "$pc_file")
libdir=$(dirname "$pc_dir")
say "library folder is ${libdir#"$prefix"/}"

[ -f "$prefix/include/penumbra/penumbra.h" ] || fail "header not installed as include/penumbra/penumbra.h"
ls "$libdir"/libpenumbra.so* >/dev/null 2>&1 || fail "no libpenumbra.so in $libdir"
[ -L "$libdir/libpenumbra.so" ] || [ -f "$libdir/libpenumbra.so" ] \
    || fail "no development link libpenumbra.so in $libdir"
config_dir=$libdir/cmake/penumbra
for f in penumbraConfig.cmake penumbraConfigVersion.cmake penumbraTargets.cmake; do
    [ -f "$config_dir/$f" ] || fail "$f not installed in $config_dir"
done
[ -x "$prefix/bin/penumbra" ] || fail "the CLI was not installed as bin/penumbra"

# --- 2. the installed package files must not point back into the source or build tree --------
# without_prefix FILE: the file with every occurrence of the prefix path cut out (the prefix
# itself may sit inside the build tree).
without_prefix() {
    awk -v p="$prefix" '{
        out = ""
        while ((i = index($0, p)) > 0) { out = out substr($0, 1, i - 1); $0 = substr($0, i + length(p)) }
        print NR ":" out $0
    }' "$1"
}
for f in "$config_dir"/*.cmake "$pc_file"; do
    if without_prefix "$f" | grep -F -e "$source_dir" -e "$build_dir" >&2; then
        fail "$f refers to the source or build tree (lines above, prefix cut out)"
    fi
    if grep -n -e 'penumbra_objects' -e 'penumbra_internal' -e 'PN_BUILDING_LIBRARY' "$f" >&2; then
        fail "$f exposes internal targets or definitions (lines above)"
    fi
done

# --- 3. a consumer built from the pkg-config flags ------------------------------------------
say "building the consumer with pkg-config"
PKG_CONFIG_PATH=$pc_dir
export PKG_CONFIG_PATH
"$PKG_CONFIG" --exists --print-errors penumbra || fail "pkg-config cannot use $pc_file"
pc_version=$("$PKG_CONFIG" --modversion penumbra) || fail "pkg-config --modversion penumbra failed"
pc_flags=$("$PKG_CONFIG" --cflags --libs penumbra) || fail "pkg-config --cflags --libs penumbra failed"
"$PKG_CONFIG" --static --libs penumbra >/dev/null || fail "pkg-config --static --libs penumbra failed"
unset PKG_CONFIG_PATH
say "pkg-config: penumbra $pc_version: $pc_flags"

# $pc_flags and $extra_flags are word-split on purpose.
# shellcheck disable=SC2086
run "$work/logs/pc-compile.log" "$CC" -std=c11 -Wall -o "$work/pc/consumer" "$here/consumer.c" \
    $extra_flags $pc_flags \
    || fail "compiling consumer.c with the pkg-config flags failed (output above)"

LD_LIBRARY_PATH=$libdir${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
export LD_LIBRARY_PATH
if command -v ldd >/dev/null 2>&1; then
    resolved=$(ldd "$work/pc/consumer" | grep 'libpenumbra\.so')
    case $resolved in
        *"$libdir/"*) ;;
        *) fail "the pkg-config consumer does not load the installed library: $resolved" ;;
    esac
fi
"$work/pc/consumer" "$missing_scene" || fail "the pkg-config consumer failed (status $?)"

# --- 3b. README.md's library example, compiled against the installed header and run ---------
say "building README.md's library example with pkg-config"
awk '/^```c$/ { inside = 1; text = ""; next }
     inside && /^```$/ { if (text ~ /#include <penumbra\/penumbra.h>/) { printf "%s", text; exit } inside = 0; next }
     inside { text = text $0 "\n" }' "$source_dir/README.md" >"$work/pc/readme_example.c"
grep -q 'pn_render(' "$work/pc/readme_example.c" || fail "no library example (a C block with pn_render) in README.md"
# shellcheck disable=SC2086
run "$work/logs/readme-compile.log" "$CC" -std=c11 -Wall -Wextra -Werror -o "$work/pc/readme_example" \
    "$work/pc/readme_example.c" $extra_flags $pc_flags \
    || fail "README.md's library example does not compile against the installed header (output above)"
cat >"$work/pc/tiny.pbrt" <<'SCENE'
LookAt 0 3 4  0 0 0  0 1 0
Camera "perspective" "float fov" [ 45 ]
Film "rgb" "integer xresolution" [ 8 ] "integer yresolution" [ 6 ]
WorldBegin
LightSource "point" "point3 from" [ 1 2 1 ] "rgb I" [ 2 2 2 ]
Material "diffuse" "rgb reflectance" [ 0.6 0.6 0.6 ]
Shape "sphere" "float radius" [ 0.5 ]
SCENE
example_out=$("$work/pc/readme_example" "$work/pc/tiny.pbrt" "$work/pc/tiny.exr") \
    || fail "README.md's library example failed on a tiny scene (status $?)"
case $example_out in
    "8x6, "*" s, "*" shadow rays/pixel") ;;
    *) fail "README.md's library example printed '$example_out'" ;;
esac
[ -s "$work/pc/tiny.exr" ] || fail "README.md's library example wrote no image"
unset LD_LIBRARY_PATH

# --- 4. a consumer built through find_package(penumbra) -------------------------------------
say "building the consumer with find_package(penumbra)"
# The package registries could hand back some other penumbra: only the prefix may be used.
# shellcheck disable=SC2086
run "$work/logs/cmake-configure.log" "$CMAKE" -S "$here" -B "$work/cmake" \
    -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_C_COMPILER="$CC" \
    -DCMAKE_PREFIX_PATH="$prefix" \
    -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF \
    -DCMAKE_FIND_USE_SYSTEM_PACKAGE_REGISTRY=OFF \
    -DCMAKE_C_FLAGS="$extra_flags" \
    -DCMAKE_EXE_LINKER_FLAGS="$extra_flags" \
    || fail "configuring tests/install/CMakeLists.txt against $prefix failed (output above)"
found_dir=$(sed -n 's/^penumbra_DIR:PATH=//p' "$work/cmake/CMakeCache.txt")
case $found_dir in
    "$prefix"/*) ;;
    *) fail "find_package(penumbra) used $found_dir instead of the package in $prefix" ;;
esac
run "$work/logs/cmake-build.log" "$CMAKE" --build "$work/cmake" \
    || fail "building the find_package consumer failed (output above)"
# The imported target gives the consumer a run path to the installed library; no
# LD_LIBRARY_PATH here.
"$work/cmake/consumer" "$missing_scene" || fail "the find_package consumer failed (status $?)"

# --- 5. the installed CLI ------------------------------------------------------------------
say "running the installed CLI"
cli_version=$("$prefix/bin/penumbra" --version) || fail "installed bin/penumbra --version failed"
case $cli_version in
    *"$pc_version"*) ;;
    *) fail "installed bin/penumbra --version printed '$cli_version', expected $pc_version" ;;
esac

say "passed"
exit 0
