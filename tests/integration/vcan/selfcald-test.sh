#!/bin/sh
# selfcald on a real vcan interface, driven by can-utils and can_traffic (run by run-vcan.sh in the
# QEMU guest or on a host vcan). Environment: IFACE, OUT, PAYLOAD (the data files of vcan_test.py),
# SELFCAL_RATE (traffic frames/s). Leaves candump.log and selfcald.log in OUT for the host checks.
# Ends with "SELFCAL-VCAN-RUN: PASS|FAIL ...".
set -u
: "${IFACE:?}" "${OUT:?}" "${PAYLOAD:?}"
T=$(mktemp -d) # scratch files (private: on a host several tests may run at once)
RATE=${SELFCAL_RATE:-2000}
P=$PAYLOAD
daemon="" dump=""
fail() {
  echo "SELFCAL-VCAN-RUN: FAIL $*"
  [ -n "$dump" ] && kill "$dump" 2>/dev/null
  [ -n "$daemon" ] && kill "$daemon" 2>/dev/null
  sleep 0.2
  echo "---- selfcald.log"; cat "$OUT/selfcald.log" 2>/dev/null
  exit 1
}
step() { echo "vcan-test: $*"; }

# Wait for one frame matching FILTER (candump syntax) within MS; print it in log format.
# The listener is started before the action that should cause the frame.
listen() { candump -L -n 1 -T "$2" "$IFACE,$1" > "$3" 2>/dev/null & }

# ---------------------------------------------------------------- start
candump -L "$IFACE" > "$OUT/candump.log" 2>"$OUT/candump.err" &
dump=$!
listen 102:7FF 15000 $T/status0
l=$!
selfcald --table "$P/table.lut" --can "$IFACE" > "$OUT/selfcald.log" 2>&1 &
daemon=$!
wait "$l"
[ -s $T/status0 ] || fail "no status frame from selfcald within 15 s"
step "selfcald up: $(cat $T/status0)"

# ---------------------------------------------------------------- positions, bad frames, noise
n=0
while read -r frame; do
  cansend "$IFACE" "$frame" || fail "cansend $frame"
  n=$((n + 1))
done < "$P/cansend1.txt"
step "sent $n positions with cansend"
# bad frames: DLC 2, DLC 0, DLC 7, remote, extended id 0x100, another node on our output id
for frame in 100#0102 100# 100#01020304050607 100#R 00000100#1122334455667788 101#0102030405060708; do
  cansend "$IFACE" "$frame" || fail "cansend $frame"
done
step "sent 6 bad frames"
# noise on other ids: standard, extended (one with the low 11 bits of 0x100), remote, random
cangen "$IFACE" -I 7A5 -L 8 -g 0 -n 100 -p 10 || fail "cangen"
cangen "$IFACE" -I 0FF -L r -g 0 -n 100 -p 10 || fail "cangen"
cangen "$IFACE" -I 103 -L r -g 0 -n 100 -p 10 || fail "cangen"
cangen "$IFACE" -e -I 1F000100 -L 8 -g 0 -n 100 -p 10 || fail "cangen"
cangen "$IFACE" -e -L r -g 0 -n 100 -p 10 || fail "cangen"
cangen "$IFACE" -R -I 200 -g 0 -n 50 -p 10 || fail "cangen"
step "sent 550 noise frames with cangen (other ids: bad frames too, by default)"
while read -r frame; do cansend "$IFACE" "$frame" || fail "cansend $frame"; done < "$P/cansend2.txt"
sleep 2.5 # status frames
kill "$dump"
wait "$dump" 2>/dev/null
dump=""
step "candump.log: $(wc -l < "$OUT/candump.log") frames"

# ---------------------------------------------------------------- simulated traffic
for traj in raster circle; do
  can_traffic -i "$IFACE" -f "$P/$traj.txt" -r "$RATE" > $T/traffic.out 2>&1
  rc=$?
  cat $T/traffic.out
  cp $T/traffic.out "$OUT/traffic-$traj.txt"
  [ $rc -eq 0 ] || fail "can_traffic $traj at $RATE frames/s"
done

# ---------------------------------------------------------------- bus-off, link down, interface gone
read -r probe answer < "$P/probe.txt"
probe_answered() { # $1: what happened before
  # candump may not listen yet when the answer comes back (a loaded host, an emulated CPU): no
  # answer at all is retried with a longer head start; a wrong answer fails at once.
  for wait_s in 0.1 0.5 1 2; do
    listen 101:7FF 3000 $T/ans
    l=$!
    sleep $wait_s
    cansend "$IFACE" "$probe" || fail "cansend probe ($1)"
    wait "$l"
    got=$(sed -n 's/.* //p' $T/ans)
    [ -n "$got" ] && break
  done
  [ "$got" = "$answer" ] || fail "after $1: answer '$got', expected '$answer'"
}
status_byte() { # wait for the next status frame; print its byte 0 in hex
  listen 102:7FF 3000 $T/st
  wait $!
  sed -n 's/.*#\(..\).*/\1/p' $T/st
}
# An error frame as a controller reports bus-off (CAN_ERR_FLAG | CAN_ERR_BUSOFF): vcan loops it
# to every socket subscribed to error frames.
cansend "$IFACE" 20000040#0000000000000000 || fail "cansend bus-off error frame"
s=$(status_byte)
[ "$s" = "41" ] || fail "status byte 0 after bus-off: '$s', expected 41 (loaded + bus-off)"
s=$(status_byte)
[ "$s" = "41" ] || fail "status byte 0 while still bus-off: '$s', expected 41"
cansend "$IFACE" 20000100#0000000000000000 || fail "cansend restarted error frame"
s=$(status_byte)
[ "$s" = "01" ] || fail "status byte 0 after the restart: '$s', expected 01"
probe_answered "bus-off and restart"
step "bus-off reported (status 0x41) and survived"

ip link set "$IFACE" down || fail "ip link set down"
sleep 0.5
# back up as a CAN FD interface (MTU 72): classic frames keep working, FD frames are answered in FD
ip link set "$IFACE" mtu 72 || fail "ip link set mtu 72"
ip link set "$IFACE" up || fail "ip link set up"
probe_answered "interface down and up"
step "interface down/up survived"

fd_probe="100##1${probe#100#}"      # CAN FD, bit-rate switch, length 8
for wait_s in 0.1 0.5 1 2; do      # as in probe_answered: retry only when nothing came back
  listen 101:7FF 3000 $T/ans
  l=$!
  sleep $wait_s
  cansend "$IFACE" "$fd_probe" || fail "cansend $fd_probe"
  wait "$l"
  got=$(sed -n 's/.* //p' $T/ans)
  [ -n "$got" ] && break
done
case $got in
  "101##"?"${answer#101#}") ;;
  *) fail "CAN FD probe: answer '$got', expected an FD frame 101##?${answer#101#}" ;;
esac
# an FD frame of length 12 is bad: no answer (counted; checked in the next status frame)
listen 101:7FF 1000 $T/ans
l=$!
sleep 0.1
cansend "$IFACE" "100##1${probe#100#}01020304" || fail "cansend FD length 12"
wait "$l"
[ -s $T/ans ] && fail "an FD frame of length 12 was answered: $(cat $T/ans)"
s=$(listen 102:7FF 3000 $T/st; wait $!; sed -n 's/.*#....\(..\)\(..\).*/\2\1/p' $T/st)
# 6 bad frames, 550 on other ids, the FD length-12 frame: 557
[ "$s" = "022D" ] || fail "status bad-frame count after the FD length-12 frame: 0x$s, expected 0x022D"
step "CAN FD: answered in FD ($got); FD length 12 counted as bad"

ip link del dev "$IFACE" || fail "ip link del"
sleep 0.5
ip link add dev "$IFACE" type vcan || fail "ip link add"
ip link set "$IFACE" up || fail "ip link set up"
sleep 1.5 # the daemon retries every second
probe_answered "interface removed and created again"
step "interface removal survived (socket reopened)"

kill -0 "$daemon" 2>/dev/null || fail "selfcald died"
kill -TERM "$daemon"
wait "$daemon"
rc=$?
daemon=""
[ $rc -eq 0 ] || fail "selfcald exit status $rc after SIGTERM"
grep -q "bus-off" "$OUT/selfcald.log" || fail "selfcald.log does not mention the bus-off"
grep -q "interface lost" "$OUT/selfcald.log" || fail "selfcald.log does not mention the interface loss"
grep -q "socket reopened" "$OUT/selfcald.log" || fail "selfcald.log does not mention the reopening"
echo "---- selfcald.log"
cat "$OUT/selfcald.log"

# ---------------------------------------------------------------- position mode
candump -L "$IFACE" > "$OUT/position.log" 2>/dev/null &
dump=$!
listen 102:7FF 15000 $T/status0
l=$!
selfcald --table "$P/table.lut" --can "$IFACE" --mode position --can-other-ids ignore \
  > "$OUT/selfcald-position.log" 2>&1 &
daemon=$!
wait "$l"
[ -s $T/status0 ] || fail "no status frame from selfcald --mode position within 15 s"
while read -r frame; do cansend "$IFACE" "$frame" || fail "cansend $frame"; done < "$P/cansend_position.txt"
# --can-other-ids ignore: the kernel filters other ids out; our own ids still count when bad
cangen "$IFACE" -I 7A5 -L 8 -g 0 -n 50 -p 10 || fail "cangen"
cangen "$IFACE" -e -I 1F000100 -L 8 -g 0 -n 50 -p 10 || fail "cangen"
cansend "$IFACE" 100#0102 || fail "cansend 100#0102"
s=$(listen 102:7FF 3000 $T/st; wait $!; sed -n 's/.*#....\(..\)\(..\).*/\2\1/p' $T/st)
[ "$s" = "0001" ] || fail "--can-other-ids ignore: bad-frame count 0x$s after 100 frames on other ids and one bad, expected 0x0001"
step "--can-other-ids ignore: other ids not counted"
sleep 0.5
kill "$dump"
wait "$dump" 2>/dev/null
dump=""
kill -TERM "$daemon"
wait "$daemon"
rc=$?
daemon=""
[ $rc -eq 0 ] || fail "selfcald --mode position: exit status $rc after SIGTERM"
step "position mode: $(grep -c ' 101#' "$OUT/position.log") answers"
rm -rf "$T"
echo "SELFCAL-VCAN-RUN: PASS"
