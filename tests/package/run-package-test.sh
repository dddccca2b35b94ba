#!/usr/bin/env bash
# Installs the build into a temporary prefix, builds tests/package/consumer against it twice
# (find_package(splatwarp CONFIG), then pkg-config) and runs both programs.
# Usage: run-package-test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build="$1"; src="$2"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
test -x "$tmp/prefix/bin/splatwarp"
cmake -S "$src/tests/package/consumer" -B "$tmp/consumer" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/consumer" >/dev/null
mkdir "$tmp/out-cmake" "$tmp/out-pc"
"$tmp/consumer/consumer" "$tmp/out-cmake"
export PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig:$tmp/prefix/lib/x86_64-linux-gnu/pkgconfig${PKG_CONFIG_PATH:+:$PKG_CONFIG_PATH}"
# shellcheck disable=SC2046
c++ -std=c++17 -O1 "$src/tests/package/consumer/main.cpp" -o "$tmp/consumer-pc" $(pkg-config --cflags --libs splatwarp)
"$tmp/consumer-pc" "$tmp/out-pc"
"$tmp/prefix/bin/splatwarp" info "$tmp/out-pc/model.glb" >/dev/null
# The Python module, when it was built, lands in the prefix's site-packages and imports from there.
module="$(find "$tmp/prefix" -name 'splatwarp.cpython-*.so' | head -n 1)"
if [ -n "$module" ]; then
  (cd "$tmp" && PYTHONPATH="$(dirname "$module")" python3 -c "import splatwarp; print(splatwarp.__file__)") >/dev/null
fi
echo "package test: installed, built with CMake and with pkg-config, ran both"
