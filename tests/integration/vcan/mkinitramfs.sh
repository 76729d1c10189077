#!/usr/bin/env bash
# Build the initramfs of the vcan test guest: busybox, the SocketCAN modules of the test kernel
# (can, can-raw, can-dev, vcan), iproute2's ip, can-utils, the given binaries with every shared
# library ldd lists (copied to the same paths), the guest /init and a payload folder.
#
# usage: mkinitramfs.sh -o OUT.cpio.gz -k KERNEL_DIR -p PAYLOAD_DIR [-b BINARY]...
#   KERNEL_DIR  the unpacked Debian kernel package (scripts/fetch-test-kernel.sh)
#   PAYLOAD_DIR copied to /payload in the guest; /init runs /payload/run.sh
#   BINARY      copied to /bin/<name> with its libraries (e.g. selfcald, can_traffic)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out="" kdir="" payload=""
bins=()
while getopts "o:k:p:b:" opt; do
  case $opt in
    o) out=$OPTARG ;;
    k) kdir=$OPTARG ;;
    p) payload=$OPTARG ;;
    b) bins+=("$OPTARG") ;;
    *) echo "usage: $0 -o OUT -k KERNEL_DIR -p PAYLOAD_DIR [-b BINARY]..." >&2; exit 2 ;;
  esac
done
[ -n "$out" ] && [ -n "$kdir" ] && [ -n "$payload" ] || {
  echo "usage: $0 -o OUT -k KERNEL_DIR -p PAYLOAD_DIR [-b BINARY]..." >&2; exit 2; }

die() { echo "mkinitramfs: $*" >&2; exit 1; }
need() { command -v "$1" >/dev/null 2>&1 || die "$1 not found (${2:-run scripts/install-deps.sh})"; }
need cpio; need gzip; need ldd
busybox=$(command -v busybox || true)
[ -n "$busybox" ] || die "busybox not found (install busybox-static)"
ldd "$busybox" >/dev/null 2>&1 && die "$busybox is not statically linked (install busybox-static)"
ipbin=$(command -v ip || echo /usr/sbin/ip)
[ -x "$ipbin" ] || die "iproute2's ip not found"
can_utils=()
for t in cansend candump cangen; do
  p=$(command -v $t || true)
  [ -n "$p" ] || die "$t not found (install can-utils)"
  can_utils+=("$p")
done

modroot=$(ls -d "$kdir"/lib/modules/*/ 2>/dev/null | head -n 1)
[ -n "$modroot" ] || die "no modules under $kdir/lib/modules (run scripts/fetch-test-kernel.sh)"

stage=$(mktemp -d "${TMPDIR:-/tmp}/selfcal-initramfs.XXXXXX")
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage"/{bin,sbin,proc,sys,dev,tmp,run,out,lib/modules,etc}

copy_with_libs() { # $1 = binary, $2 = path in the guest
  local src=$1 dst=$2
  cp -L "$src" "$stage$dst"
  chmod 755 "$stage$dst"
  # "libX => /path (addr)" and "/lib64/ld-linux-x86-64.so.2 (addr)"
  ldd "$src" 2>/dev/null | awk '/=> \//{print $3} /^[ \t]*\//{print $1}' | while read -r lib; do
    case "$lib" in
      /lib/*|/lib64/*|/usr/lib/*|/usr/lib64/*) ;;
      # the project's own libraries (libselfcal.so.N from the build tree): the binaries find
      # them through RUNPATH $ORIGIN/../lib, which is /lib for /bin/<name> in the guest
      *) [ -e "$stage/lib/$(basename "$lib")" ] || cp -L "$lib" "$stage/lib/$(basename "$lib")"
         continue ;;
    esac
    [ -e "$stage$lib" ] && continue
    mkdir -p "$stage$(dirname "$lib")"
    cp -L "$lib" "$stage$lib"
  done
}

cp -L "$busybox" "$stage/bin/busybox"
chmod 755 "$stage/bin/busybox"
copy_with_libs "$ipbin" /sbin/ip
for p in "${can_utils[@]}"; do copy_with_libs "$p" "/bin/$(basename "$p")"; done
for b in "${bins[@]}"; do
  [ -x "$b" ] || die "binary $b not found"
  copy_with_libs "$b" "/bin/$(basename "$b")"
done

# The four modules, decompressed on the host (busybox insmod reads plain .ko), in load order.
n=0
for m in net/can/can net/can/can-raw drivers/net/can/dev/can-dev drivers/net/can/vcan; do
  f=$(ls "$modroot"kernel/$m.ko* 2>/dev/null | head -n 1)
  [ -n "$f" ] || die "module $m missing in $modroot"
  n=$((n + 1))
  dst="$stage/lib/modules/$n-$(basename "$m").ko"
  case $f in
    *.ko) cp "$f" "$dst" ;;
    *.ko.xz) xz -dc "$f" > "$dst" ;;
    *.ko.zst) zstd -qdc "$f" > "$dst" ;;
    *.ko.gz) gzip -dc "$f" > "$dst" ;;
    *) die "unknown module format $f" ;;
  esac
done

cp "$here/guest-init.sh" "$stage/init"
chmod 755 "$stage/init"
mkdir -p "$stage/payload"
cp -R "$payload"/. "$stage/payload/"
echo "root:x:0:0:root:/:/bin/sh" > "$stage/etc/passwd"

mkdir -p "$(dirname "$out")"
(cd "$stage" && find . -print0 | LC_ALL=C sort -z | cpio --null -o -H newc --quiet -R 0:0) |
  gzip -1 > "$out.tmp"
mv "$out.tmp" "$out"
