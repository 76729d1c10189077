#!/usr/bin/env bash
# Install what is needed, build everything under AddressSanitizer and UBSan, run every test.
# Then the same sanitizers with clang (whose UBSan sees what GCC's misses, e.g. pointer
# arithmetic that wraps), with the libFuzzer targets: the unit tests and a short run of each
# fuzz target (label fuzz-short, about 20 s each) in build-clang (not the dense reference
# comparison test_grid_lsq_dense: minutes under clang's instrumentation, and GCC's pass runs it).
# SELFCAL_SKIP_CLANG=1 skips the clang pass.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"
scripts/install-deps.sh
build=${SELFCAL_BUILD_DIR:-build-asan}
cmake -S . -B "$build" -G Ninja -DSELFCAL_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build" -j"$(nproc)"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
(cd "$build" && ctest --output-on-failure -j"$(nproc)" "$@")

if [ "${SELFCAL_SKIP_CLANG:-0}" != 1 ] && command -v clang >/dev/null; then
  clang_build=${SELFCAL_CLANG_BUILD_DIR:-build-clang}
  CC=clang CXX=clang++ cmake -S . -B "$clang_build" -G Ninja -DSELFCAL_SANITIZE=ON -DSELFCAL_FUZZ=ON \
    -DSELFCAL_BUILD_BENCH=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  cmake --build "$clang_build" -j"$(nproc)"
  (cd "$clang_build" && ctest --output-on-failure -j"$(nproc)" -L "unit|fuzz-short" -E "test_grid_lsq_dense")
fi
