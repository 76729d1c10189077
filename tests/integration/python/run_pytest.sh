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
# `pip wheel ./python` makes a wheel holding the module and its library, not the C source
"$venv/bin/python" -m pip wheel -q --no-deps -w "$venv/wheel" "$src/python"
"$venv/bin/python" - "$venv/wheel" <<'PY'
import glob, sys, zipfile
w = glob.glob(sys.argv[1] + "/selfcal-*.whl")
assert len(w) == 1, w
names = zipfile.ZipFile(w[0]).namelist()
for need in ("selfcal/__init__.py", "selfcal/libselfcal.so"):
    assert need in names, (need, names)
# one copy of the library: a wheel stores a symlink as a second copy
assert len([n for n in names if "libselfcal.so" in n]) == 1, names
assert any(n.startswith("selfcal/_native.") and n.endswith(".so") for n in names), names
assert not any(n.endswith(".c") for n in names), names
print("wheel:", w[0].rsplit("/", 1)[1], len(names), "files")
PY
cd "$venv"   # import the installed package, not the source folder
SELFCAL_CLI=$cli exec "$venv/bin/python" -m pytest -q -p no:cacheprovider "$src/python/tests"
