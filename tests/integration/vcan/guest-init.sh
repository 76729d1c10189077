#!/bin/busybox sh
# /init of the vcan test guest: mount the pseudo file systems, load the SocketCAN modules, create
# vcan0, run /payload/run.sh (which ends with a line "SELFCAL-VCAN-RUN: PASS|FAIL ..."), ship /out
# back on the second serial port, power off.
# The result line "SELFCAL-VCAN-RESULT: ..." is printed on the console (the first serial port).
/bin/busybox --install -s /bin
export PATH=/bin:/sbin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
mount -t tmpfs tmpfs /tmp
exec </dev/console >/dev/console 2>&1

fail() {
  echo "SELFCAL-VCAN-RESULT: FAIL $*"
  poweroff -f
  sleep 10
}

for m in /lib/modules/*.ko; do
  insmod "$m" || fail "insmod $m"
done
ip link add dev vcan0 type vcan || fail "ip link add vcan0"
ip link set up vcan0 || fail "ip link set up vcan0"
ip link set lo up

# Guest parameters from the kernel command line (selfcal.*=value), e.g. selfcal.mode=bench.
for w in $(cat /proc/cmdline); do
  case $w in
    selfcal.*=*) k=${w%%=*}; k=${k#selfcal.}; export "SELFCAL_$(echo "$k" | tr a-z A-Z)=${w#*=}" ;;
  esac
done

export IFACE=vcan0 OUT=/out PAYLOAD=/payload
cd /payload
sh /payload/run.sh 2>&1 | tee /tmp/run.log
result=$(sed -n 's/^SELFCAL-VCAN-RUN: //p' /tmp/run.log | tail -n 1)
# Ship the output files back: "@@FILE name" lines, the content, "@@END".
stty -F /dev/ttyS1 raw -echo 2>/dev/null
{
  cp /tmp/run.log /out/run.log
  for f in /out/*; do
    [ -f "$f" ] || continue
    echo "@@FILE ${f##*/}"
    cat "$f"
    echo "@@END"
  done
} > /dev/ttyS1
sync
[ -n "$result" ] || result="FAIL run.sh printed no result line"
echo "SELFCAL-VCAN-RESULT: $result"
poweroff -f
sleep 10
