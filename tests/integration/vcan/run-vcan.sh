#!/usr/bin/env bash
# Run a SocketCAN test script on a real vcan interface: on this host when it can create one
# (ip link add ... type vcan works: root or CAP_NET_ADMIN and the vcan module), otherwise in a
# Debian kernel booted under QEMU (software emulation) from an initramfs built on the fly.
# Never skips: a missing QEMU, kernel or tool is a failure with a message saying what to install.
#
# usage: run-vcan.sh --script S --work DIR [--data FILE]... [--bin BINARY]... [--param K=V]...
#                    [--kernel-dir D] [--timeout S] [--mem MB] [--smp N] [--force-qemu]
#   S        the test script; it runs with IFACE (the vcan interface), OUT (a folder for files to
#            bring back), PAYLOAD (the folder holding S as run.sh and the data files) and
#            SELFCAL_<K>=V for each --param, and ends with "SELFCAL-VCAN-RUN: PASS|FAIL ...".
#   DIR      work folder: the initramfs, console.log, and the files the script left in OUT.
# Exit status 0 only when the script reports PASS.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../../.." && pwd)
script="" work="" kdir=${SELFCAL_KERNEL_DIR:-$repo/.cache/kernel}
timeout_s=150 mem=768 smp=1 force_qemu=${SELFCAL_VCAN_FORCE_QEMU:-0}
datas=() bins=() params=()
while [ $# -gt 0 ]; do
  case $1 in
    --script) script=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    --data) datas+=("$2"); shift 2 ;;
    --bin) bins+=("$2"); shift 2 ;;
    --param) params+=("$2"); shift 2 ;;
    --kernel-dir) kdir=$2; shift 2 ;;
    --timeout) timeout_s=$2; shift 2 ;;
    --mem) mem=$2; shift 2 ;;
    --smp) smp=$2; shift 2 ;;
    --force-qemu) force_qemu=1; shift ;;
    *) echo "run-vcan: unknown argument $1" >&2; exit 2 ;;
  esac
done
[ -n "$script" ] && [ -n "$work" ] || { echo "run-vcan: --script and --work are required" >&2; exit 2; }
die() { echo "run-vcan: FAIL: $*" >&2; exit 1; }

rm -rf "$work/out" "$work/payload" "$work/where.txt"
mkdir -p "$work/out" "$work/payload"
cp "$script" "$work/payload/run.sh"
for d in "${datas[@]}"; do cp "$d" "$work/payload/"; done

result_of() { sed -n "s/^$1: //p" "$2" | tr -d '\r' | tail -n 1; }

# ---------------------------------------------------------------- on the host, if it has vcan
host_if="scv$$"
if [ "$force_qemu" != 1 ] && ip link add dev "$host_if" type vcan 2>/dev/null; then
  trap 'ip link del dev "$host_if" 2>/dev/null || true' EXIT
  ip link set up "$host_if"
  echo "run-vcan: running on the host's vcan interface $host_if"
  echo "host vcan" > "$work/where.txt"
  path=$PATH
  for b in "${bins[@]}"; do path="$(cd "$(dirname "$b")" && pwd):$path"; done
  envs=(IFACE="$host_if" OUT="$work/out" PAYLOAD="$work/payload" PATH="$path")
  for p in "${params[@]}"; do envs+=("SELFCAL_$(echo "${p%%=*}" | tr a-z A-Z)=${p#*=}"); done
  set +e
  (cd "$work/payload" && env "${envs[@]}" timeout "$timeout_s" sh ./run.sh) 2>&1 | tee "$work/console.log"
  set -e
  result=$(result_of SELFCAL-VCAN-RUN "$work/console.log")
  echo "SELFCAL-VCAN-RESULT: ${result:-FAIL no result line}"
  case $result in PASS*) exit 0 ;; *) exit 1 ;; esac
fi

# ---------------------------------------------------------------- in a QEMU guest
command -v qemu-system-x86_64 >/dev/null ||
  die "qemu-system-x86_64 not found and this host cannot create a vcan interface (install qemu-system-x86)"
vmlinuz=$(ls "$kdir"/boot/vmlinuz-* 2>/dev/null | head -n 1 || true)
[ -n "$vmlinuz" ] ||
  die "no test kernel in $kdir and this host cannot create a vcan interface (run scripts/fetch-test-kernel.sh)"
echo "run-vcan: this host has no vcan; booting $(basename "$vmlinuz") under QEMU"
echo "QEMU guest ($(basename "$vmlinuz"), TCG, $smp vCPU)" > "$work/where.txt"
mkargs=(-o "$work/initramfs.cpio.gz" -k "$kdir" -p "$work/payload")
for b in "${bins[@]}"; do mkargs+=(-b "$b"); done
"$here/mkinitramfs.sh" "${mkargs[@]}"
# no_timer_check: under a loaded host the emulated CPU can miss the kernel's early IO-APIC timer
# check, which then panics ("IO-APIC + timer doesn't work"); virtual machines skip that check.
append="console=ttyS0 quiet panic=-1 oops=panic no_timer_check"
for p in "${params[@]}"; do append="$append selfcal.$p"; done
rm -f "$work/ttyS1.txt"
set +e
timeout "$timeout_s" qemu-system-x86_64 -m "$mem" -smp "$smp" -display none -no-reboot \
  -monitor none -serial stdio -serial "file:$work/ttyS1.txt" -nic none \
  -kernel "$vmlinuz" -initrd "$work/initramfs.cpio.gz" -append "$append" </dev/null 2>&1 |
  tee "$work/console.log"
rc=${PIPESTATUS[0]}
set -e
[ "$rc" = 124 ] && echo "run-vcan: the guest did not finish within ${timeout_s} s" >&2
# Unpack the files shipped on the second serial port.
if [ -f "$work/ttyS1.txt" ]; then
  tr -d '\r' < "$work/ttyS1.txt" | awk -v dir="$work/out" '
    /^@@FILE / { f = dir "/" substr($0, 8); printf "" > f; next }
    /^@@END$/ { close(f); f = ""; next }
    f != "" { print >> f }'
fi
result=$(result_of SELFCAL-VCAN-RESULT "$work/console.log")
echo "run-vcan: result: ${result:-FAIL no result line (see $work/console.log)}"
case $result in PASS*) exit 0 ;; *) exit 1 ;; esac
