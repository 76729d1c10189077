#!/usr/bin/env bash
# The portable wheel, as a user without the build dependencies gets it: scripts/build-wheel.sh
# makes it (manylinux tag, FFTW grafted, CHOLMOD and its BLAS bundled), a fresh venv installs it
# with numpy (pinned) and nothing else, and the examples run with LD_LIBRARY_PATH empty and the
# system's copies of every bundled library hidden: in a mount namespace of its own (unshare -m),
# /dev/null is bound over each of them, so a library the wheel failed to carry cannot be found.
# The least-squares example then proves that CHOLMOD and FFTW came from the wheel.
# usage: test_wheel.sh SOURCE_DIR WORK_DIR
set -euo pipefail
src=$1 work=$2
rm -rf "$work"
mkdir -p "$work"
wheel=$("$src/scripts/build-wheel.sh" "$work/dist")
echo "wheel: $(basename "$wheel") ($(du -h "$wheel" | cut -f1))"
case "$(basename "$wheel")" in
  selfcal-*-manylinux_2_*_x86_64.whl) ;;
  *) echo "FAIL: not a manylinux wheel: $wheel" >&2; exit 1 ;;
esac
python3 -m venv "$work/venv"
"$work/venv/bin/python" -m pip install -q --disable-pip-version-check numpy==2.2.6 "$wheel"

# every system file the wheel carries a copy of (through its real path: the symlinks too)
hide=()
for lib in libfftw3.so.3 libcholmod.so.3 libamd.so.2 libcamd.so.2 libccolamd.so.2 libcolamd.so.2 \
           libsuitesparseconfig.so.5 libmetis.so.5 libblas.so.3 liblapack.so.3 libopenblas.so.0 \
           libgfortran.so.5 libquadmath.so.0 libgomp.so.1; do
  for d in /usr/lib/x86_64-linux-gnu /lib/x86_64-linux-gnu; do
    [ -e "$d/$lib" ] && hide+=("$(readlink -f "$d/$lib")")
  done
done
mkdir -p "$work/run"
cat > "$work/run/hidden.sh" <<SH
set -e
for f in $(printf '%q ' "${hide[@]}"); do mount --bind /dev/null "\$f"; done
cd "$work/run"
exec env -u LD_LIBRARY_PATH "\$@"
SH
hidden() { unshare -m --propagation private sh "$work/run/hidden.sh" "$@"; }
# the hiding works: the system's FFTW cannot be loaded in there
if hidden python3 -c 'import ctypes; ctypes.CDLL("libfftw3.so.3")' 2>/dev/null; then
  echo "FAIL: the system's libfftw3 is still loadable inside the namespace" >&2; exit 1
fi
hidden "$work/venv/bin/python" "$src/examples/python/calibrate_stage.py" | tee "$work/run/example.log"
grep -q "identifiable" "$work/run/example.log"
hidden "$work/venv/bin/python" - <<'PY'
import os, selfcal
meas, truth = selfcal.simulate_grid("double-shift", n=11, sigma_r_um=0.01, seed=3)
r = selfcal.calibrate_grid(meas, method="lsq")        # CHOLMOD, through dlopen
maps = open("/proc/self/maps").read()
libs = {l.split()[-1] for l in maps.splitlines() if ".so" in l.split()[-1]}
site = os.path.dirname(selfcal.__file__) + ".libs"
for name in ("libcholmod.so.3", "libopenblas.so.0", "libfftw3-"):
    hits = [p for p in libs if os.path.basename(p).startswith(name)]
    assert hits and all(p.startswith(site) for p in hits), (name, hits, site)
print("from the wheel:", sorted(os.path.basename(p) for p in libs if p.startswith(site)))
err = float(abs(r.gx_um - truth["gx_um"]).max())
assert err < 0.05, err
print("max |Gx - truth| =", err, "um")
PY
echo "ok: the wheel runs with the system's libraries hidden"
