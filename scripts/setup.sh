#!/usr/bin/env bash
# Install the Debian packages splatwarp needs. Idempotent: does nothing when all are present.
# Runs as root, or through sudo when available.
set -euo pipefail
PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config
  libopenvdb-dev libnanovdb-dev libopenvdb-tools python3-openvdb
  libtbb-dev libeigen3-dev libopenexr-dev libpng-dev
  libgtest-dev libcli11-dev nlohmann-json3-dev libnanoflann-dev libboost-iostreams-dev zlib1g-dev
  libzstd-dev  # .spz version 4
  libassimp-dev libjpeg-dev  # meshes (OBJ/PLY/glTF/OFF) and their JPEG textures: image ground truth
  clang libclang-rt-14-dev  # scripts/fuzz.sh: libFuzzer targets (clang 14 on Debian 12)
  pybind11-dev python3-numpy python3-pytest  # python/: the `import splatwarp` module and its pytest tests
)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "setup: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  SUDO="sudo"
fi
echo "setup: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
