"""selfcal.verify: the same verdict, statistics and U as `selfcal verify` on the same files, the
guarded decision rule's three outcomes, and its errors."""
from pathlib import Path
from typing import Callable

import pytest

import selfcal
from conftest import Cli


@pytest.fixture
def files(cli: Cli, tmp_path: Path) -> Callable[[str], str]:
    def p(x: str) -> str:
        return str(tmp_path / x)
    cli("simulate", "grid", "--plan", "double-shift", "--n", 9, "--seed", 3, "--sigma-r-um", 0.01,
        "--out", p("in.csv"), "--truth-map", p("gt.csv"))
    cli("grid", "--method", "lsq", p("in.csv"), "--map", p("G.csv"), "--artifact", p("A.csv"))
    cli("lut", "build", "--map", p("G.csv"), "-o", p("T.lut"))
    with open(p("plan1.csv"), "w") as f:
        f.write("# selfcal-grid v1\n# N = 9\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0\n")
    cli("simulate", "grid", "--plan", p("plan1.csv"), "--seed", 3, "--sigma-r-um", 0.01,
        "--out", p("V.csv"), "--truth-map", p("gt1.csv"), "--compensate-with", p("T.lut"))
    return p


def kv(out: str) -> "dict[str, str]":
    return dict(l.split(": ", 1) for l in out.splitlines())


def test_equals_cli(cli: Cli, files: Callable[[str], str]) -> None:
    p = files
    for rule in ("simple", "guarded"):
        r = selfcal.verify(p("V.csv"), p("T.lut"), p("A.csv"), tolerance_um=0.1, decision_rule=rule)
        c = cli("verify", p("V.csv"), "--table", p("T.lut"), "--artifact", p("A.csv"),
                "--tolerance-um", 0.1, "--decision-rule", rule, check=False)
        k = kv(c.stdout)
        assert c.returncode == r.exit_status
        assert k["verdict"].split()[0] == r.verdict and k["decision_rule"] == rule
        assert float(k["after_max_um"]) == pytest.approx(r.after_max_um, rel=1e-5)
        assert float(k["U_verify_um"]) == pytest.approx(r.U_um, rel=1e-3)
        assert r.marks == int(k["marks"]) == 81


def test_three_outcomes(files: Callable[[str], str]) -> None:
    p = files
    mx = selfcal.verify(p("V.csv"), p("T.lut"), p("A.csv"), tolerance_um=1).after_max_um
    U = 0.4 * mx
    for T, want in ((mx + 1.2 * U, "pass"), (mx - 1.2 * U, "fail"), (mx, "inconclusive")):
        r = selfcal.verify(p("V.csv"), p("T.lut"), p("A.csv"), tolerance_um=T,
                           decision_rule="guarded", u_verify_um=U)
        assert r.verdict == want and r.U_given and r.U_um == U
    r = selfcal.verify(p("V.csv"), p("T.lut"), p("A.csv"), tolerance_um=1, decision_rule="guarded",
                       sigma_r_um=0.01, u_plate_um=0.02)
    assert r.sigma_source == "given" and r.U_um == pytest.approx(2 * (0.01**2 + 0.02**2) ** 0.5, rel=1e-3)


def test_errors(files: Callable[[str], str], tmp_path: Path) -> None:
    p = files
    with pytest.raises(ValueError):
        selfcal.verify(p("V.csv"), p("T.lut"), p("A.csv"), tolerance_um=1, decision_rule="strict")
    with pytest.raises(ValueError):
        selfcal.verify(p("V.csv"), p("T.lut"), p("A.csv"), tolerance_um=0)
    with pytest.raises(selfcal.Error, match="nothing.csv"):
        selfcal.verify(str(tmp_path / "nothing.csv"), p("T.lut"), p("A.csv"), tolerance_um=1)
