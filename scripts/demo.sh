#!/usr/bin/env bash
# The main job, end to end on a fresh Debian machine:
#   simulate an XY stage with a known error map and an uncalibrated grid plate, "measure" the
#   plate in the four views of Petrò's double shift as a measuring machine would export them
#   (one file per view, points shuffled, in µm, ';' and decimal commas, a damaged mark missing
#   and a speck of dust measured as a stray point), number the points with `selfcal import grid`,
#   calibrate (separate the stage error from the plate error), build the lookup table, start
#   selfcald on Modbus TCP (loopback), stream a trajectory through it, and compare the positions
#   before and after correction with the truth.
# Outputs go to out/ (CSV, SVG plots, the table); the summary is printed at the end.
# Options (environment): DEMO_N (plate marks per side, default 25), DEMO_SEED (default 1),
#   DEMO_METHOD (lsq | double-shift | ye; default lsq; the closed forms need every mark, so with
#   them no mark is left out of the exports), DEMO_POINTS (default 2000),
#   DEMO_SKIP_DEPS=1 (do not run install-deps.sh), DEMO_BUILD_DIR (default build).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"

N=${DEMO_N:-25}
SEED=${DEMO_SEED:-1}
METHOD=${DEMO_METHOD:-lsq}
POINTS=${DEMO_POINTS:-2000}
BUILD=${DEMO_BUILD_DIR:-build}
OUT="$here/out"

step() { printf '\n== %s\n' "$*"; }

if [ "${DEMO_SKIP_DEPS:-0}" != 1 ]; then
  step "installing dependencies (scripts/install-deps.sh)"
  scripts/install-deps.sh
fi

step "building (Release, $BUILD/)"
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSELFCAL_SANITIZE=OFF >/dev/null
cmake --build "$BUILD" --target selfcal_cli selfcald -j"$(nproc)"
SELFCAL="$BUILD/bin/selfcal"
SELFCALD="$BUILD/bin/selfcald"
PY="$here/.venv/bin/python"

mkdir -p "$OUT"
rm -rf "$OUT"/demo_*

plan=$METHOD
[ "$METHOD" = lsq ] && plan=double-shift
step "simulating a stage (known error map G) and a plate (N = $N, plan $plan), measured in each view"
"$SELFCAL" simulate grid --plan "$plan" --n "$N" --pitch-mm 1 --seed "$SEED" \
  --sigma-g-um 1 --sigma-a-um 1 --sigma-r-um 0.01 \
  --out "$OUT/demo_simulated.csv" --truth-map "$OUT/demo_G_true.csv" \
  --truth-artifact "$OUT/demo_A_true.csv" --truth-summary "$OUT/demo_truth.json"

step "the measuring machine's exports: one file per view, shuffled, um, ';' and decimal commas"
missing=()
if [ "$METHOD" = lsq ]; then missing=(--missing 3,4); fi  # a damaged mark, in no view
"$SELFCAL" simulate exports "$OUT/demo_simulated.csv" --dir "$OUT/demo_exports" --units um \
  "${missing[@]}" --stray 2 --seed "$SEED" >/dev/null
for f in "$OUT"/demo_exports/view*.csv; do
  echo "  $(basename "$f"): $(($(wc -l <"$f") - 1)) points, e.g. '$(sed -n 2p "$f")'"
done

step "numbering the points: selfcal import grid"
c=$(( (N - 1) / 2 ))
views=(--view "rot=0 shift=0,0" "$OUT/demo_exports/view0.csv"
       --view "rot=90 shift=0,0" "$OUT/demo_exports/view1.csv")
if [ "$plan" = ye ]; then
  views+=(--view "rot=0 shift=1,0" "$OUT/demo_exports/view2.csv")
else
  views+=(--view "rot=0 shift=2,0" "$OUT/demo_exports/view2.csv"
          --view "rot=0 shift=-3,0 rows=$c cols=$c,$((c + 1))" "$OUT/demo_exports/view3.csv")
fi
"$SELFCAL" import grid --n "$N" --pitch-mm 1 --units um --x-col X --y-col Y "${views[@]}" \
  -o "$OUT/demo_measured.csv" 2>&1 | sed -e "s|$OUT/||g" -e 's/^selfcal import grid: /  /'
grep '^# view' "$OUT/demo_measured.csv" | sed 's/^/  /'

step "calibrating: selfcal grid --method $METHOD"
"$SELFCAL" grid --method "$METHOD" "$OUT/demo_measured.csv" --map "$OUT/demo_G_est.csv" \
  --artifact "$OUT/demo_A_est.csv" --summary "$OUT/demo_summary.json" \
  --plot "$OUT/demo_map.svg"
"$PY" - "$OUT/demo_G_true.csv" "$OUT/demo_G_est.csv" <<'PYEOF'
import csv, math, sys
def load(p):
    return {(int(r["i"]), int(r["j"])): (float(r["gx_um"]), float(r["gy_um"]))
            for r in csv.DictReader(open(p))}
t, e = load(sys.argv[1]), load(sys.argv[2])
d = [math.hypot(e[k][0] - t[k][0], e[k][1] - t[k][1]) for k in t]
g = [math.hypot(*t[k]) for k in t]
rms = lambda v: math.sqrt(sum(x * x for x in v) / len(v))
print(f"  stage error G at the {len(t)} nodes: RMS {rms(g) * 1e3:.1f} nm; "
      f"estimate - truth: RMS {rms(d) * 1e3:.1f} nm, max {max(d) * 1e3:.1f} nm")
PYEOF

step "building the lookup table: selfcal lut build"
"$SELFCAL" lut build --map "$OUT/demo_G_est.csv" -o "$OUT/demo_stage.lut"

step "starting selfcald on Modbus TCP (loopback, a free port)"
LOG="$OUT/demo_selfcald.log"
"$SELFCALD" --table "$OUT/demo_stage.lut" --modbus-tcp 127.0.0.1:0 2>"$LOG" &
DPID=$!
cleanup() {
  if kill -0 "$DPID" 2>/dev/null; then
    kill -TERM "$DPID" 2>/dev/null || true
    wait "$DPID" 2>/dev/null || true
  fi
}
trap cleanup EXIT INT TERM
PORT=""
for _ in $(seq 1 200); do
  PORT=$(sed -n 's/.*listening on 127\.0\.0\.1:\([0-9]*\).*/\1/p' "$LOG" | head -1)
  if [ -n "$PORT" ] && grep -q ready "$LOG"; then break; fi
  if ! kill -0 "$DPID" 2>/dev/null; then cat "$LOG" >&2; echo "demo: selfcald failed" >&2; exit 1; fi
  sleep 0.05
done
[ -n "$PORT" ] || { cat "$LOG" >&2; echo "demo: selfcald did not start" >&2; exit 1; }
sed 's/^/  /' "$LOG"

step "streaming a trajectory ($POINTS points: raster + circle) through selfcald"
set +e
"$PY" scripts/demo-stream.py --port "$PORT" --truth "$OUT/demo_G_true.csv" \
  --csv "$OUT/demo_trajectory.csv" --svg "$OUT/demo_error.svg" --points "$POINTS" \
  | tee "$OUT/demo_result.txt"
rc=${PIPESTATUS[0]}
set -e
kill -TERM "$DPID"
wait "$DPID" || { echo "demo: selfcald did not stop cleanly" >&2; exit 1; }
trap - EXIT INT TERM

step "summary"
echo "  stage simulated: N = $N marks, pitch 1 mm, seed $SEED; calibrated with $METHOD"
sed -n 's/^\(before\|after\|improvement\)/  \1/p' "$OUT/demo_result.txt"
echo "  files: $OUT/demo_error.svg (error before/after), $OUT/demo_map.svg (estimated map),"
echo "         $OUT/demo_trajectory.csv, $OUT/demo_stage.lut, $OUT/demo_G_true.csv, $OUT/demo_G_est.csv"
if [ "$rc" -ne 0 ]; then
  echo "demo: FAILED (the correction did not reduce the error as expected, status $rc)" >&2
  exit 1
fi
echo "demo: ok"
