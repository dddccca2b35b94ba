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
  libwebp-dev  # SOG: lossless WebP images (meta.json + images, folder or .sog zip)
  libassimp-dev libjpeg-dev  # meshes (OBJ/PLY/glTF/OFF) and their JPEG textures: image ground truth
  clang libclang-rt-14-dev  # scripts/fuzz.sh: libFuzzer targets (clang 14 on Debian 12)
  # `splatwarp edit`'s server: small, a thread pool, enough for loopback JSON + binary (progress is
  # polled: no WebSocket library needed); Debian's build is a header plus a shared library.
  libcpp-httplib-dev
  chromium  # Edit.BrowserEndToEnd: the editor page in headless Chromium (software GL), about a minute
  pybind11-dev python3-numpy python3-pytest  # python/: the `import splatwarp` module and its pytest tests
)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
else
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "setup: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
    SUDO="sudo"
  fi
  echo "setup: installing ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# node and npm for the interop tests (tests/interop): by command, not by package, since a NodeSource
# nodejs bundles npm and conflicts with Debian's npm package. Debian 12 gives node 18 and npm 9.
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  echo "setup: installing nodejs npm"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends nodejs npm
fi
# The interop tests' peer, PlayCanvas splat-transform, at the version tests/interop/package-lock.json
# pins (no install scripts: the only one, webgpu's, is for macOS). Skipped when that lock file is
# already installed (it is copied into node_modules after a successful install).
interop="$(cd "$(dirname "$0")/.." && pwd)/tests/interop"
if ! cmp -s "$interop/package-lock.json" "$interop/node_modules/.splatwarp-installed-lock.json" 2>/dev/null; then
  echo "setup: npm ci in tests/interop (@playcanvas/splat-transform)"
  (cd "$interop" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error &&
   cp package-lock.json node_modules/.splatwarp-installed-lock.json)
fi

# The editor's page renderer (playcanvas) and its browser test's driver (puppeteer-core), pinned by
# package-lock.json; node_modules/ is git-ignored. Re-run when the lock file changed.
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if ! command -v npm >/dev/null; then
  echo "setup: npm not found: the editor page (splatwarp edit) will not load and its browser test skips" >&2
elif [ ! -f "$ROOT/node_modules/.package-lock.json" ] || ! cmp -s "$ROOT/package-lock.json" "$ROOT/node_modules/.splatwarp-lock"; then
  echo "setup: npm ci (playcanvas, puppeteer-core)"
  (cd "$ROOT" && npm ci --no-audit --no-fund --loglevel=error && cp package-lock.json node_modules/.splatwarp-lock)
fi
