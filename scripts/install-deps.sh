#!/usr/bin/env bash
# Install everything selfcal needs to build, test and run its demo on a fresh Debian machine.
# Safe to run again: it only installs what is missing.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)

DEB_PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libfftw3-dev libmodbus-dev libcmocka-dev liblapacke-dev liblapack-dev libopenblas-dev libsuitesparse-dev
  libfast-float-dev libdragonbox-dev
  gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm
  qemu-system-x86 busybox-static can-utils iproute2 cpio gzip
  mbpoll socat python3 python3-pip python3-venv
  clang libclang-rt-14-dev
  chromium poppler-utils
  # LinuxCNC (uspace): halcompile builds the HAL component selfcal_xy, halrun tests it
  # (util-linux: unshare and setpriv, which that test uses)
  linuxcnc-uspace linuxcnc-uspace-dev util-linux
  groff-base
  gcovr
  # strace: the fault tests check the mode a temporary file is created with
  strace
  # the packages' test: dpkg-shlibdeps and dpkg-architecture (dpkg-dev), lintian, and
  # systemd-analyze verify on the installed unit (systemd; procps: its ExecReload /bin/kill)
  dpkg-dev lintian systemd procps
)

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

missing=()
for p in "${DEB_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# Python peers for the integration tests, and lizard for the code_metrics test (versions pinned
# in tests/requirements.txt), in a venv inside the project so nothing global is touched.
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$here/tests/requirements.txt"

# A Debian kernel with SocketCAN modules, for the vcan tests under QEMU (not installed: unpacked).
if [ -x "$here/scripts/fetch-test-kernel.sh" ]; then
  "$here/scripts/fetch-test-kernel.sh"
fi
echo "install-deps: ok"
