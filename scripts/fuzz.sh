#!/usr/bin/env bash
# Long libFuzzer campaigns over every fuzz target (issue 15): builds build-fuzz with clang,
# ASan+UBSan and -DSELFCAL_FUZZ=ON, then runs each target for SECONDS (default 600) from its seed
# corpus, its regressions and what earlier campaigns found (kept in build-fuzz/corpus/<target>,
# never in the repository). RUNS=N stops each target after N executions instead (-runs=N; with
# SECONDS given too, whichever comes first). Prints one line per target: seconds it ran,
# executions, exec/s, coverage (edges), features, corpus size, and the crash files if any
# (build-fuzz/crashes/<target>/); each target's libFuzzer log is build-fuzz/fuzz-<target>.log.
# usage: [RUNS=10000000] [JOBS=1] [NICE=5] [MAX_LEN=65536] scripts/fuzz.sh [SECONDS] [TARGET...]
#        (JOBS=2 runs two targets at once; NICE lowers the campaign's priority; MAX_LEN caps the
#        input size in bytes: stream targets such as modbus_rtu slow down as their inputs grow)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"
runs=${RUNS:-}
if [ $# -gt 0 ] && [[ $1 =~ ^[0-9]+$ ]]; then secs=$1; shift
elif [ -n "$runs" ]; then secs=0          # -max_total_time=0: no time limit, stop at RUNS
else secs=600; fi
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(grid_read profile_read stage_map profile_result table
                                     selfcald_config modbus_adu modbus_rtu can_frame import plate_map dabam
                                     verify plot_xy)
build=${SELFCAL_FUZZ_BUILD_DIR:-build-fuzz}
CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DSELFCAL_FUZZ=ON -DSELFCAL_BUILD_BENCH=OFF \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build" -j"$(nproc)" --target $(printf 'fuzz_%s ' "${targets[@]}") >/dev/null
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1}
run_one() {
  local t=$1 work="$build/corpus/$t" crashes="$build/crashes/$t" log="$build/fuzz-$t.log"
  mkdir -p "$work" "$crashes"
  local dirs=("$work" "tests/fuzz/$t/corpus")
  [ -d "tests/fuzz/$t/regressions" ] && dirs+=("tests/fuzz/$t/regressions")
  local dict=()
  [ -f "tests/fuzz/$t/dict" ] && dict=(-dict="tests/fuzz/$t/dict")
  local limit=(-max_total_time="$secs") start end
  [ -n "$runs" ] && limit+=(-runs="$runs")
  start=$(date +%s)
  nice -n "${NICE:-0}" "$build/fuzz/fuzz_$t" "${limit[@]}" -timeout=10 -rss_limit_mb=2048 -max_len="${MAX_LEN:-65536}" \
    -print_final_stats=1 -artifact_prefix="$crashes/" "${dict[@]}" "${dirs[@]}" >"$log" 2>&1 || true
  end=$(date +%s)
  local execs rate cov ft corp
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo 0)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo 0)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo 0)
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo 0)
  corp=$(ls "$work" | wc -l)
  printf '| fuzz_%-16s | %6s s | %12s | %8s | %6s | %6s | %6s | %s |\n' "$t" "$((end - start))" "$execs" "$rate" \
    "$cov" "$ft" "$corp" "$(ls "$crashes" | tr '\n' ' ')"
}
echo "| target                | time     | executions   | exec/s   | edges  | features | corpus | findings |"
echo "|---|---|---|---|---|---|---|---|"
jobs=${JOBS:-1}
for t in "${targets[@]}"; do
  run_one "$t" &
  while [ "$(jobs -r | wc -l)" -ge "$jobs" ]; do wait -n; done
done
wait
