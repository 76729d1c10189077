#!/usr/bin/env bash
# Fetch a Debian kernel with SocketCAN modules for the vcan tests under QEMU.
# The package is downloaded (apt-get download, no root needed) and unpacked with dpkg -x into a
# cache folder; nothing is installed. Idempotent: returns at once when the kernel is already there.
#
# Cache folder: $SELFCAL_KERNEL_DIR, else <repo>/.cache/kernel (gitignored).
# Prints nothing on success when cached; "fetch-test-kernel: ok <path>" after a fetch.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
dest=${SELFCAL_KERNEL_DIR:-$here/.cache/kernel}

have_kernel() {
  local d=$1
  compgen -G "$d/boot/vmlinuz-*" >/dev/null || return 1
  local m
  for m in net/can/can net/can/can-raw drivers/net/can/dev/can-dev drivers/net/can/vcan; do
    compgen -G "$d/lib/modules/*/kernel/$m.ko*" >/dev/null || return 1
  done
  return 0
}

if have_kernel "$dest"; then
  exit 0
fi

# linux-image-amd64 is a meta package: its first dependency names the real image package.
pkg=$(apt-cache depends linux-image-amd64 2>/dev/null |
      sed -n 's/^ *Depends: \(linux-image-[0-9][^ ]*-amd64\)$/\1/p' | head -n 1)
if [ -z "$pkg" ]; then
  # The package lists may be missing on a fresh machine.
  SUDO=""; if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  pkg=$(apt-cache depends linux-image-amd64 |
        sed -n 's/^ *Depends: \(linux-image-[0-9][^ ]*-amd64\)$/\1/p' | head -n 1)
fi
if [ -z "$pkg" ]; then
  echo "fetch-test-kernel: cannot resolve the kernel package behind linux-image-amd64" >&2
  exit 1
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/selfcal-kernel.XXXXXX")
chmod 755 "$work"  # apt-get download drops privileges to _apt when run as root
trap 'rm -rf "$work"' EXIT
if ! (cd "$work" && apt-get download -q "$pkg" >/dev/null 2>&1); then
  # stale package lists name a version the mirror no longer has: refresh and resolve again
  SUDO=""; if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  pkg=$(apt-cache depends linux-image-amd64 |
        sed -n 's/^ *Depends: \(linux-image-[0-9][^ ]*-amd64\)$/\1/p' | head -n 1)
  (cd "$work" && apt-get download -q "$pkg" >/dev/null)
fi
deb=$(ls "$work"/*.deb)
mkdir -p "$work/x"
dpkg -x "$deb" "$work/x"
if ! have_kernel "$work/x"; then
  echo "fetch-test-kernel: $pkg has no vmlinuz or no CAN modules" >&2
  exit 1
fi
# Keep only what the tests need: the kernel and the modules tree (no firmware, docs).
rm -rf "$dest.new"
mkdir -p "$dest.new/boot" "$dest.new/lib"
cp "$work"/x/boot/vmlinuz-* "$dest.new/boot/"
mv "$work/x/lib/modules" "$dest.new/lib/modules"
echo "$pkg" > "$dest.new/PACKAGE"
rm -rf "$dest"
mv "$dest.new" "$dest"
echo "fetch-test-kernel: ok $dest ($pkg)"
