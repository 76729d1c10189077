#!/usr/bin/env bash
# Mutation testing (issue 43): does a test fail when the code has a realistic bug? For each mutant
# of the chosen source files (one operator at one place: < for <=, a flipped sign, + for -, && for
# ||, a constant off by one, a negation dropped), rebuilds only what the file's tests need in a
# separate Release build of a copy of the sources (build-mutate/, ccache) and runs only those
# tests (tests/mutation/modules.txt), with a time limit per mutant. Prints each mutant's fate, the
# score per module and every survivor; tests/mutation/equivalent.txt explains the equivalent ones
# (not run, not counted). The checkout itself is never modified. docs/testing.md has the figures.
# usage: scripts/mutate.sh [--module M]... [--per-module K [--seed S]] [--sample-file F]
#                          [--func REGEX] [--list] [--timeout SECONDS] [--fail-on-survivor] [FILE...]
#        NICE=15 (default) lowers its priority; the builds run one job at a time (--jobs 1).
#        e.g. scripts/mutate.sh --per-module 40            a seeded sample of 40 per module
#             scripts/mutate.sh runtime/modbus_map.c       every mutant of one file
#             scripts/mutate.sh --sample-file tests/mutation/ci_sample.txt --fail-on-survivor
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
exec nice -n "${NICE:-15}" python3 "$here/mutate.py" "$@"
