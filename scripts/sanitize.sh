#!/usr/bin/env bash
# Build with AddressSanitizer + UndefinedBehaviorSanitizer into build-asan (CUDA off, -O1 -g) and
# run the whole test suite; any sanitizer report stops the process and fails its test.
# Extra arguments go to ctest (e.g. -R BadInput).
set -euo pipefail
cd "$(dirname "$0")/.."
# ccache keys on paths relative to the checkout's parent, so clones and worktrees in other folders
# (CI's, a second checkout) reuse each other's objects.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$(cd .. && pwd)}"
start=$(date +%s)
SAN="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer"
# -g1 (line tables) is all a sanitizer's stack trace reads, and compiles 25-50% faster than -g on
# the OpenVDB-heavy files (vdb/Volume.cpp: 164 -> 111 s), the bulk of CI's time.
# The Python module is left out: an ASan-built extension cannot load into a python3 that is not
# (its C++ is the library code the C++ tests run here; Python.Module then skips).
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSPLATWARP_CUDA=OFF -DSPLATWARP_PYTHON=OFF \
  -DCMAKE_CXX_FLAGS="$SAN" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DCMAKE_EXE_LINKER_FLAGS="$SAN" -DCMAKE_SHARED_LINKER_FLAGS="$SAN" >/dev/null
cmake --build build-asan -j"$(nproc)"
built=$(date +%s)
echo "sanitize: build $((built - start)) s"
export ASAN_OPTIONS=halt_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1
export LSAN_OPTIONS="suppressions=$PWD/scripts/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
cd build-asan && ctest --output-on-failure -j"$(nproc)" "$@"
echo "sanitize: tests $(( $(date +%s) - built )) s"
