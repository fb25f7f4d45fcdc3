#!/bin/sh
# make_seeds.sh — regenerates the seed corpora of tests/fuzz/corpus (the committed files).
# usage: sh tests/fuzz/seeds/make_seeds.sh BUILD_DIR      (BUILD_DIR holds a built penumbra)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
build=$1
cc -O1 -o "$build/make_jpeg_seeds" "$here/make_jpeg_seeds.c" -ljpeg
python3 "$here/make_seeds.py" "$here/../corpus" "$build/penumbra" "$build/make_jpeg_seeds"
