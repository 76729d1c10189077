"""What the export and table tests share: the command line, a work folder, a failure list that
lets one run report every problem before it fails, a selfcal step that must succeed, and the
clamped linear interpolation the controllers and selfcald apply to a 1-D table."""
import os
import re
import subprocess
import sys


class Checks:
    """`selfcal ARGS` (run: exit status, stdout, stderr), files in the work folder (path), and
    checks that collect failures until finish."""

    def __init__(self, cli, work, stream=sys.stderr):
        self.cli, self.work, self.stream = cli, work, stream
        os.makedirs(work, exist_ok=True)
        self.failures = []

    def check(self, cond, what):
        if not cond:
            self.failures.append(what)
            print("FAIL:", what, file=self.stream)

    def run(self, *args):
        p = subprocess.run([self.cli, *args], capture_output=True, text=True, timeout=60)
        return p.returncode, p.stdout, p.stderr

    def path(self, name):
        return os.path.join(self.work, name)

    def selfcal(self, *args, timeout=300):
        """A step the test builds on: its stdout; the test stops if it fails."""
        p = subprocess.run([self.cli, *args], capture_output=True, text=True, timeout=timeout)
        if p.returncode != 0:
            print(p.stdout, p.stderr, file=sys.stderr)
            sys.exit(f"selfcal {args[0]} failed")
        return p.stdout

    def finish(self, name):
        if self.failures:
            print(f"{len(self.failures)} failure(s)")
            sys.exit(1)
        print(f"{name}: all checks passed")


class Export(Checks):
    """Checks whose run is `selfcal export ARGS`."""

    def run(self, *args):
        return Checks.run(self, "export", *args)


def precision_maps(c):
    """The two maps the precision-stage exports are tried on, calibrated by least squares in c's
    work folder: the demo's (scripts/demo.sh: 25 x 25 at 1 mm, seed 1, sigmas 1, 1, 0.01 um) as
    demo.csv, and a stitched rectangular stage (41 x 31 nodes at 2 mm, a 15 x 15 plate) as
    stitch.csv. Returns their paths."""
    c.selfcal("simulate", "grid", "--plan", "double-shift", "--out", c.path("demo_in.csv"),
              "--truth-map", c.path("demo_truth.csv"), "--n", "25", "--pitch-mm", "1", "--seed",
              "1", "--sigma-g-um", "1", "--sigma-a-um", "1", "--sigma-r-um", "0.01")
    c.selfcal("grid", "--method", "lsq", c.path("demo_in.csv"), "--map", c.path("demo.csv"))
    c.selfcal("simulate", "grid", "--plan", "stitch", "--stage", "41,31", "--n", "15",
              "--pitch-mm", "2", "--out", c.path("stitch_in.csv"), "--truth-map",
              c.path("stitch_truth.csv"), "--seed", "2")
    c.selfcal("grid", "--method", "lsq", c.path("stitch_in.csv"), "--map", c.path("stitch.csv"))
    return c.path("demo.csv"), c.path("stitch.csv")


def parse_lut_dump(text, check):
    """`selfcal lut dump` output (SPEC §3) read strictly, each point of its form passed to
    check(cond, what): the grid {(i, j): (x_mm, y_mm, gx_um, gy_um)} and the profiles
    [(axis, dir, [(n, pos_mm, err_um), ...]), ...] in their order."""
    lines = text.splitlines()
    check(lines[0] == "i,j,x_mm,y_mm,gx_um,gy_um", "dump header")
    grid, profiles, k = {}, [], 1
    while k < len(lines) and not lines[k].startswith("#"):
        i, j, x, y, gx, gy = lines[k].split(",")
        grid[(int(i), int(j))] = (float(x), float(y), float(gx), float(gy))
        k += 1
    while k < len(lines):
        m = re.fullmatch(r"# profile (\d+): axis=([xyz]) dir=([xyz])", lines[k])
        check(m is not None and int(m.group(1)) == len(profiles), f"profile line: {lines[k]!r}")
        check(lines[k + 1] == "n,pos_mm,err_um", "profile header")
        rows = []
        k += 2
        while k < len(lines) and not lines[k].startswith("#"):
            n, pos, err = lines[k].split(",")
            rows.append((int(n), float(pos), float(err)))
            k += 1
        profiles.append((m.group(2), m.group(3), rows))
    return grid, profiles


def interp_clamped(xs, vs, s):
    """Linear interpolation over ascending xs, the end values beyond them (selfcald's profile
    rule, SPEC §4; ISG within its table; Automation1's "nearest end point")."""
    if s <= xs[0]:
        return vs[0]
    if s >= xs[-1]:
        return vs[-1]
    lo, hi = 0, len(xs) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xs[mid] <= s:
            lo = mid
        else:
            hi = mid
    f = (s - xs[lo]) / (xs[hi] - xs[lo])
    return vs[lo] * (1 - f) + vs[hi] * f


def read_beckhoff_plane(path):
    """A Beckhoff/ISG plane compensation file (kw.crosscomp2) as (table, header): table maps
    (index master2, index master1) to the correction, header each kw.crosscomp2.* and kopf.*
    key to its text value."""
    tab, hdr = {}, {}
    with open(path) as f:
        for line in f:
            m = re.match(r"kw\.crosscomp2\.table\[\s*(\d+)\]\[\s*(\d+)\]\.correction\s+(-?\d+)",
                         line)
            if m:
                tab[(int(m.group(1)), int(m.group(2)))] = int(m.group(3))
                continue
            m = re.match(r"(kw\.crosscomp2\.\w+|kopf\.\w+)\s+(\S+)", line)
            if m:
                hdr[m.group(1)] = m.group(2)
    return tab, hdr
