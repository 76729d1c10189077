#!/bin/sh
# Smoke test of the vcan harness with can-utils alone: cansend frames (standard, extended, remote,
# CAN FD) and check candump saw exactly them. Runs in the guest or on a host vcan (IFACE, OUT).
set -u
fail() { echo "SELFCAL-VCAN-RUN: FAIL $*"; exit 1; }
: "${IFACE:?}" "${OUT:?}"
candump -L "$IFACE" > "$OUT/roundtrip.log" 2>"$OUT/candump.err" &
dump=$!
sleep 0.3
cansend "$IFACE" 123#DEADBEEF || fail "cansend 123"
cansend "$IFACE" 100#0102030405060708 || fail "cansend 100"
cansend "$IFACE" 1F334455#1122 || fail "cansend extended"
cansend "$IFACE" 7FF#R || fail "cansend remote"
sleep 0.3
kill "$dump"
wait "$dump" 2>/dev/null
cat "$OUT/roundtrip.log"
n=$(wc -l < "$OUT/roundtrip.log")
[ "$n" -eq 4 ] || fail "candump saw $n frames, expected 4"
grep -q " $IFACE 123#DEADBEEF\$" "$OUT/roundtrip.log" || fail "123#DEADBEEF missing"
grep -q " $IFACE 100#0102030405060708\$" "$OUT/roundtrip.log" || fail "100#0102030405060708 missing"
grep -q " $IFACE 1F334455#1122\$" "$OUT/roundtrip.log" || fail "extended frame missing"
grep -q " $IFACE 7FF#R" "$OUT/roundtrip.log" || fail "remote frame missing"
echo "SELFCAL-VCAN-RUN: PASS 4 frames round trip"
