#!/usr/bin/env bash
# The test command: installs what it needs, then builds and tests a Release
# build and an ASan+UBSan build. Exit status 0 = everything passed.
#   tools/test.sh            all of it
#   STEMD_TEST_SKIP_SANITIZE=1 tools/test.sh   Release only (quick local loop)
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)

tools/install-deps.sh

step() { printf '\n== %s (%s)\n' "$1" "$(date +%T)"; }

step "Release build"
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build/release -j "$jobs"
step "Release tests"
ctest --test-dir build/release --output-on-failure -j "$jobs"

if [ "${STEMD_TEST_SKIP_SANITIZE:-0}" != 1 ]; then
  step "ASan+UBSan build"
  cmake -S . -B build/asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g" \
    -DSTEMD_SANITIZE=address -DSTEMD_BUILD_BENCH=OFF >/dev/null
  cmake --build build/asan -j "$jobs"
  step "ASan+UBSan tests"
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build/asan --output-on-failure -j "$jobs"
fi
step "all tests passed"
