#!/bin/sh
# install-deps.sh — installs the Debian 12 packages penumbra needs, only those that are missing.
# usage: sh scripts/install-deps.sh [EXTRA_PACKAGE...]
set -eu
# Extra package names may be given as arguments (e.g. clang-format, for `make format`).
packages="build-essential cmake pkg-config libembree-dev libopenexr-dev libstb-dev libcjson-dev openmpi-bin libopenmpi-dev libpng-dev libjpeg-dev $*"
missing=""
for p in $packages; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing="$missing $p"
  fi
done
[ -z "$missing" ] && exit 0
echo "penumbra: installing missing Debian packages:$missing"
if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends $missing
