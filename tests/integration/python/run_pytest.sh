#!/usr/bin/env bash
# The Python package's acceptance: a fresh venv, `pip install ./python` (builds libselfcal and the
# extension with the project's CMake), then the pytest suite, compared against the command line.
# usage: run_pytest.sh SOURCE_DIR VENV_DIR SELFCAL_CLI
set -euo pipefail
src=$1 venv=$2 cli=$3
rm -rf "$venv"
python3 -m venv "$venv"
export PIP_DISABLE_PIP_VERSION_CHECK=1 CMAKE_BUILD_PARALLEL_LEVEL=${CMAKE_BUILD_PARALLEL_LEVEL:-2}
# the sanitizer settings of the C test build are not the package's
unset CFLAGS LDFLAGS
"$venv/bin/python" -m pip install -q -r "$src/python/requirements-test.txt"
"$venv/bin/python" -m pip install -q "$src/python"
# `pip wheel ./python` makes a wheel holding the module (libselfcal linked in: no libselfcal.so
# that LD_LIBRARY_PATH could replace) and the licences, not the C source
"$venv/bin/python" -m pip wheel -q --no-deps -w "$venv/wheel" "$src/python"
"$venv/bin/python" - "$venv/wheel" <<'PY'
import glob, sys, zipfile
w = glob.glob(sys.argv[1] + "/selfcal-*.whl")
assert len(w) == 1, w
names = zipfile.ZipFile(w[0]).namelist()
for need in ("selfcal/__init__.py", "selfcal/LICENSE", "selfcal/COPYRIGHT", "selfcal/py.typed",
             "selfcal/_native.pyi"):
    assert need in names, (need, names)
assert not any("libselfcal" in n for n in names), names
assert any(n.startswith("selfcal/_native.") and n.endswith(".so") for n in names), names
assert not any(n.endswith(".c") for n in names), names
print("wheel:", w[0].rsplit("/", 1)[1], len(names), "files")
PY
cd "$venv"   # import the installed package, not the source folder
# the module carries its library: a libselfcal.so of another build on LD_LIBRARY_PATH is not
# loaded (a decoy that exits the interpreter if it were)
mkdir -p "$venv/decoy"
printf '#include <stdlib.h>\n__attribute__((constructor)) static void decoy(void) { exit(99); }\n' \
    > "$venv/decoy/decoy.c"
cc -shared -fPIC -o "$venv/decoy/libselfcal.so" "$venv/decoy/decoy.c"
cp "$venv/decoy/libselfcal.so" "$venv/decoy/libselfcal.so.0"
LD_LIBRARY_PATH="$venv/decoy" "$venv/bin/python" -c 'import selfcal; assert selfcal.version()'
"$venv/bin/python" - <<'PY'
import selfcal, os, glob
mod = selfcal._native.__file__
maps = open("/proc/self/maps").read()
assert "libselfcal" not in maps, [l for l in maps.splitlines() if "libselfcal" in l]
print("module", os.path.basename(mod), "self-contained")
PY
SELFCAL_CLI=$cli exec "$venv/bin/python" -m pytest -q -p no:cacheprovider "$src/python/tests"
