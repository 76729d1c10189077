"""Shared fixtures: the command line to compare with (SELFCAL_CLI, set by CTest; tests that need
it are skipped without it) and a scratch folder per test."""
import os
import shutil
import subprocess
from typing import Protocol

import numpy as np
import numpy.typing as npt
import pytest


class Cli(Protocol):
    """The `cli` fixture: runs `selfcal ARGS...`; raises AssertionError on a non-zero exit when
    check is True."""

    def __call__(self, *args: object, check: bool = True) -> "subprocess.CompletedProcess[str]": ...


@pytest.fixture(scope="session")
def cli() -> Cli:
    exe = os.environ.get("SELFCAL_CLI") or shutil.which("selfcal")
    if not exe:
        pytest.skip("no selfcal command line to compare with (set SELFCAL_CLI)")

    def run(*args: object, check: bool = True) -> "subprocess.CompletedProcess[str]":
        p = subprocess.run([exe, *map(str, args)], capture_output=True, text=True, timeout=300)
        if check and p.returncode != 0:
            raise AssertionError(f"selfcal {' '.join(map(str, args))}: exit {p.returncode}\n{p.stderr}")
        return p

    return run


def read_csv(path: "str | os.PathLike[str]") -> "dict[str, npt.NDArray[np.float64]]":
    """A CSV file with a header line as a dict of float arrays (empty cells -> NaN); '#' lines skipped."""
    with open(path) as f:
        lines = [l.rstrip("\n") for l in f if l.strip() and not l.startswith("#")]
    names = lines[0].split(",")
    cols: "dict[str, list[float]]" = {k: [] for k in names}
    for l in lines[1:]:
        for k, v in zip(names, l.split(",")):
            cols[k].append(float(v) if v != "" else float("nan"))
    return {k: np.array(v) for k, v in cols.items()}
