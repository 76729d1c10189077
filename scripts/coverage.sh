#!/usr/bin/env bash
# Line and branch coverage of libselfcal and the runtime (selfcald), measured with gcov/gcovr.
#
#   scripts/coverage.sh                 # build in build-coverage, run the tests, print the figures
#   scripts/coverage.sh -L unit         # extra arguments go to ctest (here: the unit tests only)
#
# Prints one summary for everything (libselfcal + runtime), then one line per area, so that the
# readers (io/) and the correction core (core/) can be watched on their own. HTML details:
# build-coverage/coverage/index.html. Built without sanitizers, -O0, so lines map to the source.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${SELFCAL_COVERAGE_BUILD:-$here/build-coverage}
cd "$here"
command -v gcovr >/dev/null || { echo "coverage: gcovr missing (scripts/install-deps.sh)" >&2; exit 1; }

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache)
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Debug -DSELFCAL_SANITIZE=OFF \
      -DSELFCAL_BUILD_BENCH=OFF "-DCMAKE_C_FLAGS=--coverage -O0" \
      -DCMAKE_EXE_LINKER_FLAGS=--coverage -DCMAKE_SHARED_LINKER_FLAGS=--coverage \
      "${launcher[@]}" >/dev/null
cmake --build "$build" -j2 >/dev/null
find "$build" -name '*.gcda' -delete
(cd "$build" && ctest -j2 --output-on-failure -E '^(soak|install)' "$@") >"$build/coverage-ctest.log" 2>&1 ||
  echo "coverage: some tests failed (see $build/coverage-ctest.log); figures are of what ran" >&2

gcov_args=(-r "$here" "$build" --gcov-ignore-parse-errors)
echo "== libselfcal and runtime"
mkdir -p "$build/coverage"
gcovr "${gcov_args[@]}" --filter 'libselfcal/' --filter 'runtime/' --print-summary \
      --html-details -o "$build/coverage/index.html" | grep -E '^(lines|branches):' 
printf '%-24s %18s %18s\n' "area" "lines" "branches"
for area in libselfcal/src/common libselfcal/src/io libselfcal/src/core libselfcal/src/grid \
            libselfcal/src/profile libselfcal/src/lut runtime; do
  # the report goes to a scratch file: gcovr replaces its output file, and with `-o /dev/null`
  # as root it replaced the device with a regular file (and broke every later redirection)
  sum=$(gcovr "${gcov_args[@]}" --filter "$area/" --print-summary -o "$build/coverage/area.txt")
  lines=$(echo "$sum" | awk '/^lines:/ {print $2, $3 "/" $6}' | tr -d '()')
  branches=$(echo "$sum" | awk '/^branches:/ {print $2, $3 "/" $6}' | tr -d '()')
  printf '%-24s %18s %18s\n' "${area#libselfcal/src/}" "$lines" "$branches"
done
