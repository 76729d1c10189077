#!/usr/bin/env bash
# Build Release (no sanitizers) and print every benchmark table. Speed and memory targets are
# checked here, not in timed tests. Pass --full for the long runs (paper-size Monte Carlo, N = 10⁶
# at d = 97/101, ...). Figures on a shared or virtual machine move by tens of per cent: repeat.
# --soak [SECONDS] runs only the selfcald soak (default 600 s: 64 clients + reload storms; 0 wrong,
# 0 lost, RSS flat), bench/soak_selfcald.py.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"
full=""
soak=""
[ "${1:-}" = "--full" ] && full="--full"
if [ "${1:-}" = "--soak" ]; then soak=${2:-600}; fi
[ "${SELFCAL_SKIP_DEPS:-0}" = 1 ] || scripts/install-deps.sh
build=${SELFCAL_BENCH_BUILD_DIR:-build-bench}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSELFCAL_SANITIZE=OFF \
  -DSELFCAL_BUILD_TESTS=OFF >/dev/null
cmake --build "$build" -j"$(nproc)"
b="$build/bench"
section() { printf '\n==================== %s ====================\n' "$*"; }
if [ -n "$soak" ]; then
  section "selfcald soak: ${soak} s, 64 clients, reload storms"
  exec python3 bench/soak_selfcald.py "$build/bin/selfcal" "$build/bin/selfcald" "$soak" 64
fi
section "grid: least squares, solve time and memory (issue: N = 25, 51, 101)"
"$b/bench_grid_lsq" ${full:+--big}
section "grid: the whole selfcal grid --method lsq command vs SuiteSparse CHOLMOD on the same matrix (issue 11: N = 101, 201, 301; 401 with full)"
"$b/bench_grid_cholmod" 101 201 301 ${full:+401}
section "grid: Monte Carlo sigma_C / sigma_r, three methods"
"$b/bench_grid_mc" $full
section "grid: the uncertainty budget's Monte Carlo (issue 34: M = 1000 at N = 25 in seconds)"
"$b/bench_grid_scale_mc" $full
section "profile: the whole command at N = 10⁶ (read, solve, write) and number conversions vs glibc"
"$b/bench_profile_command" 1000010 "$build/bin/selfcal"
section "profile: least squares, dense vs fast"
"$b/bench_profile_lsq" $full
section "profile: dense LS, fast LS, DFT"
"$b/bench_profile" $full
section "correction core: ns per apply(), table size"
"$b/bench_core_apply"
section "selfcald: Modbus TCP round trip, 1 and 64 clients"
"$b/bench_modbus"
section "selfcald: CAN frames/s through the daemon (QEMU guest with vcan)"
"$b/bench_can"
section "python: Table.apply on 10⁶ points vs the C core (issue 14: >= 50 M points/s)"
pyvenv="$build/pyvenv"
[ -x "$pyvenv/bin/python" ] || python3 -m venv "$pyvenv"
"$pyvenv/bin/python" -m pip install -q --disable-pip-version-check -r python/requirements-test.txt
CMAKE_BUILD_PARALLEL_LEVEL=$(nproc) "$pyvenv/bin/python" -m pip install -q --disable-pip-version-check ./python
"$pyvenv/bin/python" bench/bench_python_apply.py "$build/bin/selfcal" "$b/bench_core_apply"
