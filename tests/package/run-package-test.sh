#!/usr/bin/env bash
# Installs the build into a temporary prefix, builds tests/package/consumer against it twice
# (find_package(splatwarp CONFIG), then pkg-config) and runs both programs.
# Usage: run-package-test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build="$1"; src="$2"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
# The consumer is compiled as the library was (a sanitizer build's library needs the sanitizer runtime).
cache() { sed -n "s/^$1:[A-Z]*=//p" "$build/CMakeCache.txt"; }
cxxflags="$(cache CMAKE_CXX_FLAGS)"; ldflags="$(cache CMAKE_EXE_LINKER_FLAGS)"
test -x "$tmp/prefix/bin/splatwarp"
cmake -S "$src/tests/package/consumer" -B "$tmp/consumer" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$tmp/prefix" -DCMAKE_CXX_FLAGS="$cxxflags" -DCMAKE_EXE_LINKER_FLAGS="$ldflags" >/dev/null
cmake --build "$tmp/consumer" >"$tmp/build.log" 2>&1 || { cat "$tmp/build.log"; exit 1; }
mkdir "$tmp/out-cmake" "$tmp/out-pc"
"$tmp/consumer/consumer" "$tmp/out-cmake"
export PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig:$tmp/prefix/lib/x86_64-linux-gnu/pkgconfig${PKG_CONFIG_PATH:+:$PKG_CONFIG_PATH}"
# shellcheck disable=SC2046,SC2086
c++ -std=c++17 -O1 $cxxflags $ldflags "$src/tests/package/consumer/main.cpp" -o "$tmp/consumer-pc" $(pkg-config --cflags --libs splatwarp)
"$tmp/consumer-pc" "$tmp/out-pc"
"$tmp/prefix/bin/splatwarp" info "$tmp/out-pc/model.glb" >/dev/null
# The Python module, when it was built, lands in the prefix's site-packages and imports from there.
module="$(find "$tmp/prefix" -name 'splatwarp.cpython-*.so' | head -n 1)"
if [ -n "$module" ]; then
  (cd "$tmp" && PYTHONPATH="$(dirname "$module")" python3 -c "import splatwarp; print(splatwarp.__file__)") >/dev/null
fi
echo "package test: installed, built with CMake and with pkg-config, ran both"
