#!/usr/bin/env bash
# mypy --strict on the Python package's examples and tests, as a user's type checker reads the
# package: from the venv python_package made (the package installed with py.typed and the stubs
# of its extension module, mypy pinned in python/requirements-test.txt); then on the package's
# own source.
# usage: run_mypy.sh SOURCE_DIR VENV_DIR
set -euo pipefail
src=$1 venv=$2
[ -x "$venv/bin/python" ] || { echo "no venv at $venv: run the python_package test first" >&2; exit 1; }
cd "$venv"   # the installed package, not the source folder; the cache stays in the venv
"$venv/bin/python" -m mypy --strict --config-file "$src/python/mypy.ini" \
    --cache-dir "$venv/.mypy_cache" "$src/python/tests" "$src/examples/python"
# and the package's own code, from its source folder (its annotations are complete)
exec "$venv/bin/python" -m mypy --strict --config-file "$src/python/mypy.ini" \
    --cache-dir "$venv/.mypy_cache_src" "$src/python/src/selfcal"
