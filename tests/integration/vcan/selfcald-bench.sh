#!/bin/sh
# CAN throughput through selfcald with nothing lost (run by run-vcan.sh; see vcan_test.py --bench).
# 1. a fixed rate (SELFCAL_RATE frames/s, default 10000, above the 8.7k frames/s of a saturated
#    1 Mbit/s bus) for SELFCAL_SECONDS (default 10): every answer checked, none may be lost;
# 2. as fast as possible with at most 512 frames in flight, for 3 s: the headroom.
# With SELFCAL_MIN_RATE set, the fixed-rate run must also reach that rate (the generator keeps
# its schedule only if the guest keeps up).
# Ends with "SELFCAL-VCAN-RUN: PASS|FAIL <figures>".
set -u
: "${IFACE:?}" "${OUT:?}" "${PAYLOAD:?}"
T=$(mktemp -d) # scratch files (private: on a host several tests may run at once)
RATE=${SELFCAL_RATE:-10000}
SECS=${SELFCAL_SECONDS:-10}
P=$PAYLOAD
daemon=""
fail() {
  echo "SELFCAL-VCAN-RUN: FAIL $*"
  [ -n "$daemon" ] && kill "$daemon" 2>/dev/null
  exit 1
}
candump -L -n 1 -T 15000 "$IFACE,102:7FF" > $T/status0 &
l=$!
selfcald --table "$P/table.lut" --can "$IFACE" > "$OUT/selfcald.log" 2>&1 &
daemon=$!
wait "$l"
[ -s $T/status0 ] || fail "no status frame from selfcald within 15 s"

can_traffic -i "$IFACE" -f "$P/circle.txt" -r "$RATE" -d "$SECS" > "$OUT/bench-rate.txt" 2>&1
rc=$?
cat "$OUT/bench-rate.txt"
fixed=$(sed -n 's/.*sent \([0-9]*\) answered \([0-9]*\) lost \([0-9]*\).*duration_s \([0-9.]*\) rate_per_s \([0-9]*\).*/sent=\1 answered=\2 lost=\3 seconds=\4 rate=\5/p' "$OUT/bench-rate.txt" | head -n 1)
can_traffic -i "$IFACE" -f "$P/circle.txt" -r 0 -w 512 -d 3 > "$OUT/bench-max.txt" 2>&1
rc2=$?
cat "$OUT/bench-max.txt"
max=$(sed -n 's/.*lost \([0-9]*\).*rate_per_s \([0-9]*\).*/lost=\1 rate=\2/p' "$OUT/bench-max.txt" | head -n 1)
kill -TERM "$daemon"
wait "$daemon"
cat "$OUT/selfcald.log"
[ $rc -eq 0 ] || fail "fixed rate $RATE/s: $fixed"
[ $rc2 -eq 0 ] || fail "windowed max rate: $max"
if [ -n "${SELFCAL_MIN_RATE:-}" ]; then
  got=$(echo "$fixed" | sed -n 's/.*rate=\([0-9]*\).*/\1/p')
  [ "${got:-0}" -ge "$SELFCAL_MIN_RATE" ] || fail "fixed rate reached $got/s < $SELFCAL_MIN_RATE/s: $fixed"
fi
echo "SELFCAL-VCAN-RUN: PASS fixed[$fixed] max_window512[$max]"
