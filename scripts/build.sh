#!/usr/bin/env bash
# Configure and build into ./build (Release). Extra arguments go to CMake's configure step.
set -euo pipefail
cd "$(dirname "$0")/.."
# ccache keys on paths relative to the checkout's parent, so clones and worktrees in other folders
# (CI's, a second checkout) reuse each other's objects.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$(cd .. && pwd)}"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build build -j"$(nproc)"
