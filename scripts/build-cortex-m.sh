#!/usr/bin/env bash
# Cross-compile the correction core (libselfcal/src/core) for a Cortex-M4F with Debian's
# gcc-arm-none-eabi (-Os, thumb, hard float fpv4-sp-d16, reduced SC_CORR_MAX_*), print its code and
# data size, and with --run-tests run the core's unit tests on QEMU's mps2-an386 (Cortex-M4) with
# semihosting.
#   usage: scripts/build-cortex-m.sh [--run-tests] [BUILD_DIR]   (default BUILD_DIR: build-cortex-m)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
run_tests=0
if [ "${1:-}" = "--run-tests" ]; then
  run_tests=1
  shift
fi
build=${1:-$here/build-cortex-m}
# Host flags (sanitizers...) must not leak into the cross build.
unset CFLAGS LDFLAGS CPPFLAGS
for tool in arm-none-eabi-gcc arm-none-eabi-size cmake; do
  command -v "$tool" >/dev/null || { echo "build-cortex-m: $tool not found (scripts/install-deps.sh installs it)" >&2; exit 1; }
done
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$here/tests/cortex-m" -B "$build" "${generator[@]}" \
    -DCMAKE_TOOLCHAIN_FILE="$here/cmake/arm-none-eabi.cmake" -DCMAKE_BUILD_TYPE=MinSizeRel >/dev/null
fi
# quiet when it builds; the compiler's messages when it does not
if ! out=$(cmake --build "$build" 2>&1); then
  printf '%s\n' "$out" >&2
  echo "build-cortex-m: the Cortex-M4 build failed" >&2
  exit 1
fi

if [ "$run_tests" -eq 0 ]; then
  echo "== correction core for Cortex-M4F ($(arm-none-eabi-gcc -dumpversion), -Os -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16)"
  echo "   capacity: $(grep -o 'SC_CORR_MAX_[A-Z_]*=[0-9]*' "$build/build.ninja" | sort -u | tr '\n' ' ')"
  echo "-- the core library (code in text, constants in text; no data, no bss):"
  arm-none-eabi-size -t "$build/libselfcal_core_m4.a" | sed 's/ (ex .*)//'
  echo "-- linked alone with -nostdlib (libgcc soft-double helpers included) plus one static table (bss):"
  arm-none-eabi-size "$build/core_footprint.elf"
  read -r text data bss _ < <(arm-none-eabi-size "$build/core_footprint.elf" | tail -1)
  echo "core footprint: flash $((text + data)) bytes, RAM $((data + bss)) bytes (sc_corr_table = $bss bytes of bss)"
  exit 0
fi

command -v qemu-system-arm >/dev/null || { echo "build-cortex-m: qemu-system-arm not found" >&2; exit 1; }
log="$build/test_core_m4.log"
# The program reports through semihosting; the verdict is QEMU's exit status (main's return value,
# the failed-test count, passed on by semihosting SYS_EXIT) and the summary line.
set +e
timeout 120 qemu-system-arm -M mps2-an386 -cpu cortex-m4 -display none -monitor none -serial null \
  -semihosting-config enable=on,target=native -kernel "$build/test_core_m4.elf" | tee "$log"
status=${PIPESTATUS[0]}
set -e
if [ "$status" -eq 0 ] && grep -q "test(s) run, 0 failed" "$log" && ! grep -q "FAILED" "$log"; then
  echo "cortex-m4 (qemu mps2-an386): core tests passed"
else
  echo "cortex-m4 (qemu mps2-an386): core tests FAILED (qemu status $status)" >&2
  exit 1
fi
