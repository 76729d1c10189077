#!/usr/bin/env bash
# Install what is needed, build everything under AddressSanitizer and UBSan, run every test.
# Then the same sanitizers with clang (whose UBSan sees what GCC's misses, e.g. pointer
# arithmetic that wraps), with the libFuzzer targets: the unit tests and a short run of each
# fuzz target (label fuzz-short, about 20 s each) in build-clang (not the dense reference
# comparison test_grid_lsq_dense: minutes under clang's instrumentation, and GCC's pass runs it).
# SELFCAL_SKIP_CLANG=1 skips the clang pass.
# Last, GCC's ThreadSanitizer on the tests of the library's own threads (label threads: the profile
# reader, the row writer, the profile least squares' plan; build-tsan, only those tests built).
# OpenBLAS's thread pool is not instrumented (its reports would be about OpenBLAS's own
# synchronisation), so that pass runs it on one thread. SELFCAL_SKIP_TSAN=1 skips it.
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

if [ "${SELFCAL_SKIP_TSAN:-0}" != 1 ]; then
  tsan_build=${SELFCAL_TSAN_BUILD_DIR:-build-tsan}
  CC=gcc CXX=g++ cmake -S . -B "$tsan_build" -G Ninja -DSELFCAL_TSAN=ON -DSELFCAL_BUILD_BENCH=OFF \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  cmake --build "$tsan_build" -j"$(nproc)" --target test_io test_profile test_profile_lsq
  # without address-space randomisation where the system allows it: GCC 12's TSan cannot start
  # under kernels that randomise with more than 28 bits (vm.mmap_rnd_bits)
  norandom=()
  if setarch "$(uname -m)" -R true 2>/dev/null; then norandom=(setarch "$(uname -m)" -R); fi
  (cd "$tsan_build" && OPENBLAS_NUM_THREADS=1 TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1} \
     "${norandom[@]}" ctest --output-on-failure -j"$(nproc)" -L threads)
fi
