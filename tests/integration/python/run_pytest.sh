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
cd "$venv"   # import the installed package, not the source folder
SELFCAL_CLI=$cli exec "$venv/bin/python" -m pytest -q -p no:cacheprovider "$src/python/tests"
