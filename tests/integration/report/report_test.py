#!/usr/bin/env python3
"""Tests of `selfcal report grid|profile`, `selfcal verify` and the plots they share.

Usage: report_test.py CLI TMPDIR CASE
Cases:
  render_grid, render_profile  the report renders in headless Chromium with the network cut off:
                               the DOM has the expected sections and inline figures, a screenshot
                               is not blank, and the file references nothing outside itself.
  numbers_grid, numbers_profile  the numbers in the report equal those of the files `selfcal
                               grid --summary/--map` and `selfcal profile --out` write for the
                               same input.
  verify                       a simulated re-measurement after compensation: a good table
                               passes, a table with the wrong sign fails (exit 3); --raw too.
  bad_input                    exit 2, one line FILE:LINE: reason, no output left.
  plots                        plot map of a plate error file, arrows inside the frame, u map,
                               worst node in mm, long titles shortened.
Standard library only.
"""
import csv
import html.parser
import json
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zlib

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import clitest  # noqa: E402  (the shared preamble: tests/integration/clitest.py)
from clitest import fail, fresh_dir, run  # noqa: E402

CLI, TMP, CASE = clitest.setup("report_")
CHROMIUM_TIMEOUT = 150  # chromium starts in 1-20 s under load; 5x margin and more


# ---------------------------------------------------------------------------------------------
# headless Chromium

def chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        p = shutil.which(name)
        if p:
            return p
    fail("chromium not found (scripts/install-deps.sh installs Debian's chromium)")


def chromium_run(html_path, *mode):
    """Run headless Chromium on a local file with every network path cut: an invalid proxy for
    all schemes and a resolver that finds no host. Returns stdout (bytes)."""
    prof = tempfile.mkdtemp(prefix="chromium-", dir=TMP)
    try:
        cmd = [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
               "--disable-extensions", "--disable-background-networking", "--disable-sync",
               "--disable-dev-shm-usage", "--user-data-dir=" + prof,
               "--proxy-server=http://127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND",
               "--proxy-bypass-list=<-loopback>"] + list(mode) + ["file://" + os.path.abspath(html_path)]
        p = subprocess.run(cmd, capture_output=True, timeout=CHROMIUM_TIMEOUT, cwd=prof)
        if p.returncode != 0:
            fail("chromium exit %d: %s" % (p.returncode, p.stderr.decode(errors="replace")[-2000:]))
        return p.stdout
    finally:
        shutil.rmtree(prof, ignore_errors=True)


def png_pixels(path):
    """Decode an 8-bit RGB/RGBA PNG (what Chromium writes): (width, height, rows of bytes)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        fail("%s: not a PNG" % path)
    pos, idat = 8, b""
    w = h = ctype = 0
    while pos < len(data):
        ln, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + ln]
        if kind == b"IHDR":
            w, h, depth, ctype = struct.unpack(">IIBB", body[:10])
            if depth != 8 or ctype not in (2, 6):
                fail("%s: PNG depth %d colour type %d not handled" % (path, depth, ctype))
        elif kind == b"IDAT":
            idat += body
        pos += 12 + ln
    raw = zlib.decompress(idat)
    bpp = 3 if ctype == 2 else 4
    stride = w * bpp
    rows, prev, off = [], bytearray(stride), 0
    for _ in range(h):
        f, line = raw[off], bytearray(raw[off + 1:off + 1 + stride])
        off += 1 + stride
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    return w, h, bpp, rows


def check_not_blank(png):
    w, h, bpp, rows = png_pixels(png)
    colours, dark = set(), 0
    for y in range(0, h, 3):
        r = rows[y]
        for x in range(0, w, 3):
            px = r[x * bpp:x * bpp + 3]
            colours.add(px)
            if sum(px) < 200:
                dark += 1
    if len(colours) < 20 or dark < 200:
        fail("%s looks blank: %d colours, %d dark samples" % (png, len(colours), dark))


EXTERNAL = [
    (r"https?:", "an http(s) URL"), (r"file:", "a file: URL"), (r"ftp:", "an ftp: URL"),
    (r"<link\b", "a <link> element"), (r"<script\b[^>]*\bsrc\s*=", "a <script src>"),
    (r"<(img|iframe|embed|object|video|audio|source)\b", "an embedded resource element"),
    (r"url\(", "a CSS url()"), (r"@import", "a CSS @import"), (r"(src|href)\s*=\s*[\"']?//", "a protocol-relative URL"),
    (r"xlink:href\s*=\s*[\"'][^#]", "an external xlink:href"),
]


def check_self_contained(path):
    text = open(path, encoding="utf-8").read()
    for pat, what in EXTERNAL:
        m = re.search(pat, text, re.I)
        if m:
            fail("%s references something outside itself: %s at offset %d: %r"
                 % (path, what, m.start(), text[max(0, m.start() - 60):m.start() + 60]))
    return text


class Cells(html.parser.HTMLParser):
    """Collects elements by id (text and data-v), counts tags, and the rows of tables."""

    def __init__(self):
        super().__init__()
        self.ids, self.count, self.stack = {}, {}, []
        self.rows, self.row = {}, None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.count[tag] = self.count.get(tag, 0) + 1
        if tag == "tr" and a.get("class") in ("node", "pt"):
            self.row = []
            self.rows.setdefault(a["class"], []).append(self.row)
        if tag == "td" and self.row is not None:
            self.row.append(a.get("data-v"))
        self.stack.append((tag, a.get("id"), a.get("data-v"), []))

    def handle_endtag(self, tag):
        while self.stack:
            t, i, v, txt = self.stack.pop()
            if i:
                self.ids[i] = (v, "".join(txt).strip())
            if self.stack:
                self.stack[-1][3].extend(txt)
            if t == tag:
                break
        if tag == "tr":
            self.row = None

    def handle_data(self, data):
        if self.stack:
            self.stack[-1][3].append(data)


def parse(text):
    c = Cells()
    c.feed(text)
    return c


# ---------------------------------------------------------------------------------------------

def simulate_grid(d, n=11, plan="double-shift", seed=3, sigma_r=0.01):
    inp, gt, at = (os.path.join(d, x) for x in ("in.csv", "G_true.csv", "A_true.csv"))
    run("simulate", "grid", "--plan", plan, "--n", n, "--seed", seed, "--sigma-r-um", sigma_r,
        "--out", inp, "--truth-map", gt, "--truth-artifact", at)
    return inp, gt, at


def render_check(html_path, must_ids, min_svg):
    text = check_self_contained(html_path)
    dom = chromium_run(html_path, "--dump-dom").decode("utf-8", errors="replace")
    c = parse(dom)
    for i in must_ids:
        if i not in c.ids:
            fail("%s: rendered DOM lacks #%s" % (html_path, i))
    if c.count.get("svg", 0) < min_svg:
        fail("%s: %d inline SVG figures in the DOM, want >= %d" % (html_path, c.count.get("svg", 0), min_svg))
    if c.count.get("h2", 0) < 5:
        fail("%s: %d sections" % (html_path, c.count.get("h2", 0)))
    png = html_path + ".png"
    chromium_run(html_path, "--screenshot=" + png, "--window-size=1100,1600", "--hide-scrollbars")
    check_not_blank(png)
    # print to PDF works (a non-trivial PDF)
    pdf = html_path + ".pdf"
    chromium_run(html_path, "--print-to-pdf=" + pdf, "--no-pdf-header-footer")
    data = open(pdf, "rb").read()
    if not data.startswith(b"%PDF") or len(data) < 20000:
        fail("%s: print to PDF gave %d bytes" % (pdf, len(data)))
    return text, c


def case_render_grid():
    d = fresh_dir("render_grid")
    inp, _, _ = simulate_grid(d)
    out = os.path.join(d, "R.html")
    run("report", "grid", inp, "-o", out, "--sigma-r-um", 0.01)
    _, c = render_check(out, ["summary", "plan", "method", "noise", "residuals", "results",
                              "provenance", "identifiable", "O", "O-u", "O-U2", "sigma_r_est_um",
                              "variance_factor", "chi2", "n_outliers", "version", "cmdline"], 6)
    sha = subprocess.run(["sha256sum", inp], capture_output=True, text=True).stdout.split()[0]
    if sha not in open(out, encoding="utf-8").read():
        fail("the report does not hold the input's SHA-256 %s" % sha)
    if c.ids["identifiable"][1] != "yes":
        fail("identifiable: %r" % (c.ids["identifiable"],))
    ver = run("--version").stdout.split()[-1]
    if ver not in c.ids["version"][1]:
        fail("version %r not in %r" % (ver, c.ids["version"]))
    # the closed forms: a report without uncertainty maps but with everything else
    out2 = os.path.join(d, "R_ds.html")
    run("report", "grid", inp, "-o", out2, "--method", "double-shift")
    render_check(out2, ["summary", "results", "provenance", "method-name"], 4)


def case_render_profile():
    d = fresh_dir("render_profile")
    inp, truth = os.path.join(d, "in.csv"), os.path.join(d, "truth.csv")
    run("simulate", "profile", "--out", inp, "--truth", truth)
    for m in ("lsq", "dft"):
        out = os.path.join(d, "R_%s.html" % m)
        run("report", "profile", inp, "-o", out, "--method", m)
        render_check(out, ["summary", "setup", "method", "noise", "residuals", "results",
                           "provenance", "uf-max", "Uf-max", "chi2", "variance_factor"], 2)


def num(c, i):
    v = c.ids.get(i)
    if v is None or v[0] is None:
        fail("report has no number #%s (%r)" % (i, v))
    return float(v[0])


def close(a, b, what, rel=1e-9, abs_=1e-12):
    if not (abs(a - b) <= abs_ + rel * abs(b)):
        fail("%s: report %r vs file %r" % (what, a, b))


def case_numbers_grid():
    d = fresh_dir("numbers_grid")
    inp, _, _ = simulate_grid(d, n=9, plan="ye", seed=5, sigma_r=0.02)
    for method, sigma in (("lsq", None), ("lsq", 0.02), ("ye", None)):
        extra = ["--sigma-r-um", sigma] if sigma else []
        g, s, out = (os.path.join(d, x) for x in ("G.csv", "S.json", "R.html"))
        run("grid", "--method", method, inp, "--map", g, "--summary", s, *extra)
        run("report", "grid", inp, "-o", out, "--method", method, *extra)
        c = parse(check_self_contained(out))
        sm = json.load(open(s))
        close(num(c, "O"), sm["O_urad"], "O (urad)")
        close(num(c, "R"), sm["R_ppm"], "R (ppm)")
        close(sm["O_urad"], sm["O"] * 1e6, "O_urad against the dimensionless O (kept through 0.3)")
        close(sm["R_ppm"], sm["R"] * 1e6, "R_ppm against the dimensionless R")
        if method == "lsq":
            close(sm["uO_urad"], sm["uO"] * 1e6, "uO_urad")
            close(sm["uR_ppm"], sm["uR"] * 1e6, "uR_ppm")
        if "µrad" not in c.ids.get("O", ("", ""))[1] and "µrad" not in open(out, encoding="utf-8").read():
            fail("the report gives O without its unit")
        for v, view in enumerate(sm["views"]):
            close(num(c, "tx-%d" % v), view["tx_um"], "tx view %d" % v)
            close(num(c, "ty-%d" % v), view["ty_um"], "ty view %d" % v)
            close(num(c, "theta-%d" % v), view["theta_urad"], "theta view %d" % v)
        close(num(c, "sigma_r_est_um"), sm["sigma_r_est_um"], "sigma_r_est")
        if method == "lsq":
            close(num(c, "sigma_r_used_um"), sm["sigma_r_used_um"], "sigma_r_used")
            close(num(c, "residual_rms_um"), sm["residual_rms_um"], "residual RMS")
            if int(c.ids["dof"][1]) != sm["dof"]:
                fail("dof %r vs %r" % (c.ids["dof"], sm["dof"]))
        # every node of the map file, as the table in the report
        rows = c.rows.get("node", [])
        with open(g) as f:
            mp = list(csv.DictReader(f))
        if len(rows) != len(mp):
            fail("report node table has %d rows, the map %d" % (len(rows), len(mp)))
        for row, m in zip(rows, mp):
            close(float(row[4]), float(m["gx_um"]), "gx node %s,%s" % (m["i"], m["j"]))
            close(float(row[5]), float(m["gy_um"]), "gy node %s,%s" % (m["i"], m["j"]))
            if m["ugx_um"]:
                close(float(row[6]), float(m["ugx_um"]), "ugx node")
                close(float(row[8]), 2 * float(m["ugx_um"]), "Ugx (k=2) node")
            elif row[6] is not None:
                fail("report gives u where the map has none")
        # residuals and outlier flags against `grid --residuals` (the same least-squares fit)
        if method == "lsq":
            rc = os.path.join(d, "R.csv")
            run("grid", "--method", method, inp, "--map", g, "--residuals", rc, *extra)
            with open(rc) as f:
                res = list(csv.DictReader(f))
            flagged = sum(int(x["outlier"]) for x in res)
            if int(c.ids["n_outliers"][1]) != flagged:
                fail("report flags %s, grid --residuals %d" % (c.ids["n_outliers"], flagged))
            views = sorted({int(x["view"]) for x in res})
            for v in views:
                rx = [float(x["rx_um"]) for x in res if int(x["view"]) == v]
                close(num(c, "rms-rx-%d" % v), math.sqrt(sum(a * a for a in rx) / len(rx)),
                      "RMS rx view %d" % v, rel=1e-9)
        # statistics the report derives, recomputed from the map file
        gx = [float(m["gx_um"]) for m in mp]
        close(num(c, "gx-rms"), math.sqrt(sum(x * x for x in gx) / len(gx)), "RMS Gx", rel=1e-9)
        close(num(c, "gx-max"), max(abs(x) for x in gx), "max |Gx|")
        if sigma:  # given sigma: variance factor = (sigma_est / sigma)^2
            close(num(c, "variance_factor"), (sm["sigma_r_est_um"] / sigma) ** 2, "variance factor", rel=1e-6)


def case_stage():
    """A stage larger than the plate (SPEC §5, 9 x 7 nodes, N = 7): the report's maps and node
    table cover every stage node, and verify works on it."""
    d = fresh_dir("stage")
    p = lambda x: os.path.join(d, x)  # noqa: E731
    views = "".join("# view %d: rot=%d shift=%d,0\n" % (k, r, s) for k, (r, s) in
                    enumerate([(0, 0), (90, 0), (0, 1), (0, -1), (0, 2), (0, -2)]))
    open(p("plan.csv"), "w").write("# selfcal-grid v1\n# N = 7\n# pitch_mm = 1\n# stage = 9,7\n" + views)
    run("simulate", "grid", "--plan", p("plan.csv"), "--seed", 4, "--out", p("in.csv"), "--truth-map", p("gt.csv"))
    run("grid", "--method", "lsq", p("in.csv"), "--map", p("G.csv"), "--artifact", p("A.csv"))
    run("report", "grid", p("in.csv"), "-o", p("R.html"))
    c = parse(check_self_contained(p("R.html")))
    if c.ids["stage"][1] != "9 × 7":
        fail("stage grid shown as %r" % (c.ids["stage"],))
    rows = c.rows.get("node", [])
    with open(p("G.csv")) as f:
        mp = list(csv.DictReader(f))
    if len(rows) != 63 or len(mp) != 63:
        fail("node table %d rows, map %d" % (len(rows), len(mp)))
    for row, m in zip(rows, mp):
        close(float(row[4]), float(m["gx_um"]), "gx node %s,%s" % (m["i"], m["j"]))
        close(float(row[6]), float(m["ugx_um"]), "ugx node %s,%s" % (m["i"], m["j"]))
    run("plot", "map", p("A.csv"), "-o", p("A.svg"))
    run("lut", "build", "--map", p("G.csv"), "-o", p("t.lut"))
    open(p("plan1.csv"), "w").write("# selfcal-grid v1\n# N = 7\n# pitch_mm = 1\n# stage = 9,7\n"
                                    "# view 0: rot=0 shift=1,0\n")
    run("simulate", "grid", "--plan", p("plan1.csv"), "--seed", 4, "--out", p("V.csv"),
        "--truth-map", p("gt1.csv"), "--compensate-with", p("t.lut"))
    run("verify", p("V.csv"), "--table", p("t.lut"), "--artifact", p("A.csv"), "--tolerance-um", 0.1)


def case_numbers_profile():
    d = fresh_dir("numbers_profile")
    inp, truth = os.path.join(d, "in.csv"), os.path.join(d, "truth.csv")
    run("simulate", "profile", "--n", 231, "--d1", 7, "--d2", 11, "--out", inp, "--truth", truth)
    for m in ("lsq", "dft"):
        pcsv, out = os.path.join(d, "P_%s.csv" % m), os.path.join(d, "R_%s.html" % m)
        run("profile", "--method", m, inp, "--out", pcsv, "--quiet")
        run("report", "profile", inp, "-o", out, "--method", m)
        c = parse(check_self_contained(out))
        with open(pcsv) as f:
            pr = list(csv.DictReader(f))
        rows = c.rows.get("pt", [])
        if len(rows) != len(pr):
            fail("%s: report table %d rows, profile file %d" % (m, len(rows), len(pr)))
        for row, p in zip(rows, pr):
            close(float(row[2]), float(p["f_um"]), "f n=%s" % p["n"], rel=1e-12, abs_=1e-12)
            close(float(row[3]), float(p["uf_um"]), "uf n=%s" % p["n"], rel=1e-12, abs_=1e-15)
            close(float(row[4]), 2 * float(p["uf_um"]), "U n=%s" % p["n"], rel=1e-12, abs_=1e-15)
            if p["ey_um"]:
                close(float(row[5]), float(p["ey_um"]), "ey n=%s" % p["n"], rel=1e-12, abs_=1e-12)
            elif row[5] is not None:
                fail("report has e_y where the file has none (n=%s)" % p["n"])
        uf = [float(p["uf_um"]) for p in pr]
        close(num(c, "uf-max"), 1e3 * max(uf), "max u(f) nm", rel=1e-12)
        close(num(c, "Uf-max"), 2e3 * max(uf), "max U(f) nm", rel=1e-12)
        f = [float(p["f_um"]) for p in pr]
        close(num(c, "f-pv"), max(f) - min(f), "f peak to valley", rel=1e-12)
    # no redundancy (N - d1 - d2 = 0) and no stated noise: what cannot be computed reads "—",
    # never "nan"
    n3 = os.path.join(d, "n3.csv")
    with open(n3, "w") as f:
        f.write("# selfcal-profile v1\n# N = 3\n# s_mm = 1\n# scan 1: d=1\n# scan 2: d=2\n"
                "scan,n,m1_um,m2_um,m3_urad\n1,0,1,1,1\n1,1,1,1,1\n2,0,1,1,1\n")
    out = os.path.join(d, "R_n3.html")
    run("report", "profile", n3, "-o", out)
    text = check_self_contained(out)
    if re.search(r">\s*-?(nan|inf)\b", text, re.I):
        fail("a report without redundancy prints nan: %r" % re.findall(r".{40}>\s*-?nan.{10}", text, re.I)[:3])


def case_outliers():
    """A gross error in one measurement: the report flags it and names it first."""
    d = fresh_dir("outliers")
    inp, _, _ = simulate_grid(d, n=9, plan="ye", seed=3, sigma_r=0.01)  # clean: variance factor 1.05
    lines = open(inp).read().splitlines()
    k = next(i for i, l in enumerate(lines) if l.startswith("1,4,5,"))
    f = lines[k].split(",")
    f[3] = "%.15f" % (float(f[3]) + 0.2e-3)  # 0.2 um = 20 sigma on x
    lines[k] = ",".join(f)
    bad = os.path.join(d, "in_outlier.csv")
    open(bad, "w").write("\n".join(lines) + "\n")
    out = os.path.join(d, "R.html")
    run("report", "grid", bad, "-o", out, "--sigma-r-um", 0.01)
    c = parse(check_self_contained(out))
    if int(c.ids["n_outliers"][1]) < 1:
        fail("a 20-sigma error is not flagged: %r" % (c.ids["n_outliers"],))
    text = open(out, encoding="utf-8").read()
    m = re.search(r'<table id="worst-residuals">.*?</tr>\n<tr><td>(\d+)</td><td>(\d+)</td><td>(\d+)</td>', text, re.S)
    if not m or m.groups() != ("1", "4", "5"):
        fail("the largest residual is not the corrupted mark (view 1, 4, 5): %s" % (m.groups() if m else None))
    if c.ids["chi2"][1] != "fail":
        fail("chi-square test passes with a 20-sigma error in the data: %r" % (c.ids["chi2"],))
    # without it the same data pass the test and flag nothing at this seed
    run("report", "grid", inp, "-o", out, "--sigma-r-um", 0.01)
    c = parse(check_self_contained(out))
    if c.ids["chi2"][1] != "pass":
        fail("clean data fail the chi-square test: %r" % (c.ids["chi2"],))
    # the outlier test's significance: 0.05 for the whole data set by default, or each
    # coordinate's own; the critical value shown is P(|Z| > crit) = that share (erfc)
    m = 2 * sum(1 for l in open(inp) if l[:1].isdigit())
    for extra, a in (([], 1 - 0.95 ** (1.0 / m)), (["--outlier-alpha-each", "0.001"], 0.001),
                     (["--outlier-alpha", "0.5"], 1 - 0.5 ** (1.0 / m))):
        run("report", "grid", inp, "-o", out, "--sigma-r-um", 0.01, *extra)
        c = parse(check_self_contained(out))
        crit = float(c.ids["outlier_crit"][1])
        if abs(math.erfc(crit / math.sqrt(2)) / a - 1) > 3e-3:  # crit to 4 decimals: 0.03 %
            fail("report %r: critical value %g for a share %g" % (extra, crit, a))
        # the standardized residuals' histogram states the same threshold
        want = "beyond ±%.2f a measurement is flagged" % crit
        if want not in open(out, encoding="utf-8").read():
            fail("report %r: the histogram caption does not say %r" % (extra, want))
    run("report", "grid", inp, "-o", out, "--outlier-alpha", "2", expect=2)
    # each view's noise estimated: listed, and the chi-square test not applicable
    run("report", "grid", inp, "-o", out, "--view-noise", "estimate")
    c = parse(check_self_contained(out))
    vs = [float(x) for x in c.ids["view_sigma_um"][1].replace("µm", "").split(",")]
    if len(vs) != 3 or not all(0.005 < x < 0.02 for x in vs) or c.ids["chi2"][1] != "not applicable":
        fail("report --view-noise estimate: %r %r" % (c.ids["view_sigma_um"], c.ids["chi2"]))
    us = [float(x) for x in c.ids["view_sigma_u_um"][1].replace("µm", "").split(",")]
    if len(us) != 3 or not all(0 < u < x for u, x in zip(us, vs)):
        fail("report: the estimates' uncertainties %r" % (c.ids["view_sigma_u_um"],))
    run("report", "grid", inp, "-o", out, "--view-noise", "estimate", "--sigma-r-um", 0.01, expect=2)
    # the plan's reliability as `selfcal plan` gives it (the default test)
    run("report", "grid", inp, "-o", out, "--sigma-r-um", 0.01)
    c = parse(check_self_contained(out))
    kv = dict(l.split(": ", 1) for l in run("plan", inp).stdout.splitlines() if ": " in l)
    if c.ids["n_testable"][1] != kv["testable_equations"] or \
            abs(float(c.ids["mdb_ratio_max"][1]) / float(kv["mdb_ratio_max"]) - 1) > 5e-3:
        fail("report reliability %r %r, plan %s %s" % (c.ids["n_testable"], c.ids["mdb_ratio_max"],
                                                       kv["testable_equations"], kv["mdb_ratio_max"]))


def write_neg_map(src, dst):
    with open(src) as f:
        rows = list(csv.reader(f))
    with open(dst, "w") as f:
        f.write(",".join(rows[0]) + "\n")
        for r in rows[1:]:
            r = list(r)
            r[4], r[5] = repr(-float(r[4])), repr(-float(r[5]))
            f.write(",".join(r) + "\n")


def piped(args, data, timeout=60):
    """Run selfcal with data on its stdin (a pipe)."""
    return subprocess.run([CLI] + [str(a) for a in args], input=data, capture_output=True,
                          timeout=timeout)


def provenance(html_path):
    """{file: (bytes, sha256)} of a report's provenance table."""
    text = open(html_path, encoding="utf-8").read()
    rows = re.findall(r'<td class="l mono">([^<]*)</td><td>(-?\d+)</td><td class="l mono sha256">'
                      r'([0-9a-f]{64})</td>', text)
    return {f: (int(b), h) for f, b, h in rows}


def case_pipes():
    """Inputs through a pipe or a FIFO are read once: the reports, verify and lut build record
    the SHA-256 and size of the bytes that came (not of an empty re-read), a FIFO does not hang,
    and a message about piped input names it as given."""
    import hashlib
    d = fresh_dir("pipes")
    p = lambda x: os.path.join(d, x)  # noqa: E731
    inp, _, _ = simulate_grid(d, n=9, plan="double-shift", seed=4)
    data = open(inp, "rb").read()
    want = (len(data), hashlib.sha256(data).hexdigest())
    r = piped(["report", "grid", "/dev/stdin", "-o", p("R1.html")], data)
    if r.returncode != 0 or provenance(p("R1.html")).get("/dev/stdin") != want:
        fail("report grid from a pipe: %r %r" % (r.stderr, provenance(p("R1.html"))))
    fifo = p("fifo")
    for rep in range(2):  # the report, then lut build, each from a FIFO a writer fills
        if os.path.exists(fifo):
            os.remove(fifo)
        os.mkfifo(fifo)
        src = data
        if rep == 1:
            run("grid", "--method", "lsq", inp, "--map", p("G.csv"))
            src = open(p("G.csv"), "rb").read()
        writer = subprocess.Popen(["sh", "-c", 'cat > "$1"', "sh", fifo], stdin=subprocess.PIPE)
        writer.stdin.write(src)
        writer.stdin.close()
        args = (["report", "grid", fifo, "-o", p("R2.html")] if rep == 0 else
                ["lut", "build", "--map", fifo, "-o", p("t.lut")])
        r = subprocess.run([CLI] + args, capture_output=True, text=True, timeout=60)
        writer.wait(timeout=60)
        if r.returncode != 0:
            fail("%s from a FIFO: %s" % (args[0], r.stderr))
        if rep == 0 and provenance(p("R2.html")).get(fifo) != want:
            fail("report grid from a FIFO: %r" % provenance(p("R2.html")))
        if rep == 1:
            info = run("lut", "info", p("t.lut")).stdout
            if hashlib.sha256(src).hexdigest() + " (map)" not in info:
                fail("lut build from a FIFO: %s" % info)
    # report profile and verify's re-measurement, piped
    run("simulate", "profile", "--n", 330, "--out", p("P.csv"), "--truth", p("T.csv"))
    pdata = open(p("P.csv"), "rb").read()
    r = piped(["report", "profile", "/dev/stdin", "-o", p("R3.html")], pdata)
    if r.returncode != 0 or provenance(p("R3.html")).get("/dev/stdin") != (
            len(pdata), hashlib.sha256(pdata).hexdigest()):
        fail("report profile from a pipe: %r %r" % (r.stderr, provenance(p("R3.html"))))
    run("grid", "--method", "lsq", inp, "--map", p("G.csv"), "--artifact", p("A.csv"))
    run("lut", "build", "--map", p("G.csv"), "-o", p("good.lut"))
    r = piped(["verify", "/dev/stdin", "--table", p("good.lut"), "--artifact", p("A.csv"),
               "--tolerance-um", 100, "--html", p("v.html")], data)
    if r.returncode != 0 or provenance(p("v.html")).get("/dev/stdin") != want:
        fail("verify from a pipe: %r %r" % (r.stderr, provenance(p("v.html"))))
    # "-" (standard input) piped, and redirected from a file: the bytes' hash either way
    r = piped(["report", "profile", "-", "-o", p("R5.html")], pdata)
    if r.returncode != 0 or provenance(p("R5.html")).get("-") != (len(pdata), hashlib.sha256(pdata).hexdigest()):
        fail("report profile -: %r %r" % (r.stderr, provenance(p("R5.html"))))
    with open(p("P.csv"), "rb") as fh:
        r = subprocess.run([CLI, "report", "profile", "-", "-o", p("R6.html")], stdin=fh,
                           capture_output=True, timeout=60)
    if r.returncode != 0 or provenance(p("R6.html")).get("-") != (len(pdata), hashlib.sha256(pdata).hexdigest()):
        fail("report profile - < file: %r %r" % (r.stderr, provenance(p("R6.html"))))
    gdata = open(p("G.csv"), "rb").read()
    r = piped(["lut", "build", "--map", "-", "-o", p("t2.lut")], gdata)
    if r.returncode != 0 or hashlib.sha256(gdata).hexdigest() + " (map)" not in run("lut", "info", p("t2.lut")).stdout:
        fail("lut build --map -: %r" % r.stderr)
    # an output naming the pipe an input comes through is refused before anything is read
    r = piped(["grid", "--method", "lsq", "/dev/stdin", "--map", "/dev/stdin"], data)
    if r.returncode != 2 or "also an input" not in r.stderr.decode():
        fail("output = piped input: %d %r" % (r.returncode, r.stderr))
    # the commands that look at their input before reading it take a pipe too
    r = piped(["plot", "map", "/dev/stdin", "-o", p("m.svg")], gdata)
    if r.returncode != 0 or not os.path.exists(p("m.svg")):
        fail("plot map from a pipe: %r" % r.stderr)
    r = piped(["simulate", "exports", "/dev/stdin", "--dir", p("exp")], data)
    if r.returncode != 0 or not os.path.exists(os.path.join(p("exp"), "view0.csv")):
        fail("simulate exports from a pipe: %r" % r.stderr)
    # an endless pipe of comments is refused while it is copied, at its line
    r = subprocess.run(["sh", "-c", 'yes "# c" | "$1" report grid - -o "$2"', "sh", CLI, p("R8.html")],
                       capture_output=True, text=True, timeout=120)
    if r.returncode != 2 or "-:1000001: more than 1000000 comment" not in r.stderr:
        fail("endless comments through a pipe: %d %r" % (r.returncode, r.stderr))
    # a device of NUL bytes is refused at once (not read for 2 GiB first)
    r = subprocess.run([CLI, "report", "profile", "/dev/zero", "-o", p("R7.html")],
                       capture_output=True, text=True, timeout=60)
    if r.returncode != 2 or "NUL byte" not in r.stderr or os.path.exists(p("R7.html")):
        fail("/dev/zero: %d %r" % (r.returncode, r.stderr))
    # a bad piped input: the message names it as given, exit 2, no report
    bad = data.replace(b"# N = 9", b"# N = x", 1)
    r = piped(["report", "grid", "/dev/stdin", "-o", p("R4.html")], bad)
    err = r.stderr.decode()
    if r.returncode != 2 or not err.startswith("selfcal: /dev/stdin:") or "/proc/" in err \
            or os.path.exists(p("R4.html")):
        fail("bad piped input: exit %d, %r" % (r.returncode, err))
    print("pipes: ok")


def case_verify(name="verify"):
    d = fresh_dir(name)
    n, seed = 11, 7
    inp, gt, _ = simulate_grid(d, n=n, plan="double-shift", seed=seed, sigma_r=0.01)
    p = lambda x: os.path.join(d, x)  # noqa: E731
    run("grid", "--method", "lsq", inp, "--map", p("G.csv"), "--artifact", p("A.csv"))
    run("lut", "build", "--map", p("G.csv"), "-o", p("good.lut"))
    write_neg_map(p("G.csv"), p("Gneg.csv"))
    run("lut", "build", "--map", p("Gneg.csv"), "-o", p("neg.lut"))
    with open(p("plan1.csv"), "w") as f:
        f.write("# selfcal-grid v1\n# N = %d\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0\n" % n)
    # re-measurements: the same stage and plate (same seed), with each table active, and raw
    for name, table in (("V_good.csv", "good.lut"), ("V_neg.csv", "neg.lut")):
        run("simulate", "grid", "--plan", p("plan1.csv"), "--seed", seed, "--sigma-r-um", 0.01,
            "--out", p(name), "--truth-map", p("gt1.csv"), "--compensate-with", p(table))
    run("simulate", "grid", "--plan", p("plan1.csv"), "--seed", seed, "--sigma-r-um", 0.01,
        "--out", p("V_raw.csv"), "--truth-map", p("gt1.csv"))
    tol = 0.1  # um: 10 x the noise; the wrong sign leaves 2 G (about 2 um)
    good = run("verify", p("V_good.csv"), "--table", p("good.lut"), "--artifact", p("A.csv"),
               "--tolerance-um", tol, "--residuals", p("res.csv"), "--plot", p("v.svg"),
               "--html", p("v.html"))
    kv = dict(l.split(": ", 1) for l in good.stdout.splitlines())
    if kv["verdict"].split()[0] != "pass" or not float(kv["after_max_um"]) <= tol:
        fail("good table: %s" % good.stdout)
    if not float(kv["before_rms_um"]) > 20 * float(kv["after_rms_um"]):
        fail("good table: before %s vs after %s" % (kv["before_rms_um"], kv["after_rms_um"]))
    # "before" is about G: compare with the truth (RMS of the vector difference < 0.1 um)
    with open(gt) as f:
        truth = {(int(r["i"]), int(r["j"])): (float(r["gx_um"]), float(r["gy_um"])) for r in csv.DictReader(f)}
    with open(p("res.csv")) as f:
        res = list(csv.DictReader(f))
    if len(res) != n * n:
        fail("residual file has %d rows" % len(res))
    # G's gauge (no translation/rotation) differs from the fitted misalignment's only by a rigid
    # motion, which the per-view fit removed from both: compare after removing it from the truth
    tx = sum(truth[(int(r["i"]), int(r["j"]))][0] - float(r["before_rx_um"]) for r in res) / len(res)
    ty = sum(truth[(int(r["i"]), int(r["j"]))][1] - float(r["before_ry_um"]) for r in res) / len(res)
    e = math.sqrt(sum((truth[(int(r["i"]), int(r["j"]))][0] - float(r["before_rx_um"]) - tx) ** 2 +
                      (truth[(int(r["i"]), int(r["j"]))][1] - float(r["before_ry_um"]) - ty) ** 2
                      for r in res) / len(res))
    if e > 0.1:
        fail("before-compensation map differs from the true G by %.3g um RMS" % e)
    check_self_contained(p("v.html"))
    vroot = ET.parse(p("v.svg")).getroot()
    heads = len(vroot.findall("{http://www.w3.org/2000/svg}polygon"))
    if heads < 2 * n * n * 0.9:  # before and after, an arrow per node each
        fail("verify --plot: %d arrow heads for two panels of %d nodes" % (heads, n * n))
    bad = run("verify", p("V_neg.csv"), "--table", p("neg.lut"), "--artifact", p("A.csv"),
              "--tolerance-um", tol, "--residuals", p("res_neg.csv"), expect=3)
    kv = dict(l.split(": ", 1) for l in bad.stdout.splitlines())
    if kv["verdict"].split()[0] != "fail" or not float(kv["after_max_um"]) > 10 * tol:
        fail("wrong-sign table: %s" % bad.stdout)
    if not os.path.exists(p("res_neg.csv")):
        fail("a failed verification still writes its residual file")
    if good.stderr:
        fail("verify of a complete re-measurement says something on stderr: %r" % good.stderr)
    # a mark missing from the re-measurement is left out, and said so
    lines = open(p("V_good.csv")).read().splitlines(True)
    data_at = next(k for k, l in enumerate(lines) if l[0].isdigit())
    with open(p("V_gap.csv"), "w") as f:
        f.writelines(lines[:data_at] + lines[data_at + 1:])
    gap = run("verify", p("V_gap.csv"), "--table", p("good.lut"), "--artifact", p("A.csv"),
              "--tolerance-um", tol)
    kvg = dict(l.split(": ", 1) for l in gap.stdout.splitlines())
    if int(kvg["marks"]) != n * n - 1 or "1 mark(s) the views place on the stage without a point" \
            not in gap.stderr:
        fail("verify with a mark missing: marks %s, stderr %r" % (kvg["marks"], gap.stderr))
    # raw readings: the table is applied here
    run("verify", p("V_raw.csv"), "--raw", "--table", p("good.lut"), "--artifact", p("A.csv"),
        "--tolerance-um", tol)
    run("verify", p("V_raw.csv"), "--raw", "--table", p("neg.lut"), "--artifact", p("A.csv"),
        "--tolerance-um", tol, expect=3)
    # and in the report
    out = p("R.html")
    run("report", "grid", inp, "-o", out, "--verify", p("V_neg.csv"), "--table", p("neg.lut"),
        "--tolerance-um", tol)
    c = parse(check_self_contained(out))
    if c.ids.get("verify-verdict", (None, ""))[1] != "fail":
        fail("report with a wrong-sign table: verdict %r" % (c.ids.get("verify-verdict"),))
    run("report", "grid", inp, "-o", out, "--verify", p("V_good.csv"), "--table", p("good.lut"),
        "--tolerance-um", tol)
    c = parse(check_self_contained(out))
    if c.ids.get("verify-verdict", (None, ""))[1] != "pass":
        fail("report with a good table: verdict %r" % (c.ids.get("verify-verdict"),))
    return d, p, tol


def case_verify_guarded():
    """The guarded decision rule (ISO 14253-1) gives each of its three outcomes, with U given and
    with U computed from its parts; the verdict line names the rule and U; the report shows it."""
    d, p, _ = case_verify("verify_guarded")
    base = ["verify", p("V_good.csv"), "--table", p("good.lut"), "--artifact", p("A.csv")]

    def kv_of(r):
        return dict(l.split(": ", 1) for l in r.stdout.splitlines())
    # the largest residual after compensation, under the simple rule
    mx = float(kv_of(run(*base, "--tolerance-um", 1))["after_max_um"])
    U = 0.5 * mx
    cases = ((mx + 1.5 * U, 0, "pass"),   # max + U <= T
             (mx - 1.5 * U, 3, "fail"),   # max - U > T
             (mx + 0.5 * U, 4, "inconclusive"), (mx - 0.5 * U, 4, "inconclusive"))
    for T, code, verdict in cases:
        r = run(*base, "--tolerance-um", "%.9g" % T, "--decision-rule", "guarded",
                "--u-verify-um", "%.9g" % U, expect=code)
        kv = kv_of(r)
        line = kv["verdict"]
        if line.split()[0] != verdict or "guarded" not in line or ("U = %.4g" % U) not in line:
            fail("guarded, T = %g, U = %g, max %g: verdict line %r, want %s" % (T, U, mx, line, verdict))
        if kv["decision_rule"] != "guarded" or abs(float(kv["U_verify_um"]) - U) > 1e-3 * U:
            fail("guarded: %s" % r.stdout)
        # the simple rule on the same T: pass or fail by max alone
        r = run(*base, "--tolerance-um", "%.9g" % T, expect=0 if mx <= T else 3)
        if kv_of(r)["verdict"].split()[:2] != ["pass" if mx <= T else "fail", "(simple,"]:
            fail("simple, T = %g: %r" % (T, kv_of(r)["verdict"]))
    # U from its parts: 2 sqrt(s^2 + uA^2 + uq^2), s and uA given; the table's quantization is
    # below 1e-4 um, so U is 2 sqrt(s^2 + uA^2) within 1 %
    s, ua = 0.2 * mx, 0.15 * mx
    want = 2 * math.sqrt(s * s + ua * ua)  # 0.5 max
    for T, code, verdict in ((mx + want + 0.1 * mx, 0, "pass"), (mx - want - 0.1 * mx, 3, "fail"),
                             (mx, 4, "inconclusive")):
        if T <= 0:
            fail("constructed tolerance %g is not positive (max %g, U %g)" % (T, mx, want))
        r = run(*base, "--tolerance-um", "%.9g" % T, "--decision-rule", "guarded",
                "--sigma-r-um", "%.9g" % s, "--u-plate-um", "%.9g" % ua, expect=code)
        kv = kv_of(r)
        if kv["verdict"].split()[0] != verdict or abs(float(kv["U_verify_um"]) - want) > 1e-2 * want:
            fail("guarded with U from its parts (want %.4g): %s" % (want, r.stdout))
    # without given parts: sigma from the residuals (an upper bound), u(A) = sigma, U > 0
    r = run(*base, "--tolerance-um", 10, "--decision-rule", "guarded")
    kv = kv_of(r)
    if not 0 < float(kv["U_verify_um"]) < 1 or kv["verdict"].split()[0] != "pass":
        fail("guarded, U computed: %s" % r.stdout)
    run("verify", p("V_good.csv"), "--table", p("good.lut"), "--artifact", p("A.csv"),
        "--tolerance-um", 1, "--decision-rule", "strict", expect=2)
    run(*base, "--tolerance-um", 1, "--decision-rule", "guarded", "--u-verify-um", "-1", expect=2)
    # the report states the rule, U and the verdict
    out = p("R_guarded.html")
    run("report", "grid", p("in.csv"), "-o", out, "--verify", p("V_good.csv"), "--table",
        p("good.lut"), "--tolerance-um", "%.9g" % mx, "--decision-rule", "guarded",
        "--u-verify-um", "%.9g" % U)
    c = parse(check_self_contained(out))
    if c.ids.get("verify-verdict", (None, ""))[1] != "inconclusive":
        fail("report, guarded: verdict %r" % (c.ids.get("verify-verdict"),))
    if "guarded" not in c.ids.get("verify-rule", (None, ""))[1] or "verify-U" not in c.ids:
        fail("report, guarded: rule %r, U %r" % (c.ids.get("verify-rule"), c.ids.get("verify-U")))


def run_long(*args):
    """selfcal with a long time limit (a 220-page PDF prints in 40 s on an idle machine)."""
    p = subprocess.run([CLI] + [str(a) for a in args], capture_output=True, text=True, timeout=900)
    if p.returncode != 0:
        fail("selfcal %s: exit %d\n%s" % (" ".join(map(str, args)), p.returncode, p.stderr))
    return p


def pdf_pages(pdf):
    """The text of each page of a PDF (pdftotext -layout), in order."""
    exe = shutil.which("pdftotext")
    if not exe:
        fail("pdftotext not found (scripts/install-deps.sh installs poppler-utils)")
    p = subprocess.run([exe, "-layout", pdf, "-"], capture_output=True, timeout=300)
    if p.returncode != 0:
        fail("pdftotext %s: %s" % (pdf, p.stderr[-500:]))
    pages = p.stdout.decode("utf-8", errors="replace").split("\f")
    return pages[:-1] if pages and not pages[-1].strip() else pages


NODE_ROW = re.compile(r"^\s*(\d+)\s+(\d+)\s+(-?[\d.]+)\s+(-?[\d.]+)(\s+-?\d+\.\d{5}){6}\s*$")


def check_grid_pdf(d, n, info):
    """report grid --pdf at N: the info fields, 'page k of m' and the report id on every page,
    every node's appendix row, no page ending in a heading."""
    inp = os.path.join(d, "in%d.csv" % n)
    run("simulate", "grid", "--plan", "double-shift", "--n", n, "--seed", 5, "--sigma-r-um", 0.01,
        "--out", inp, "--truth-map", os.path.join(d, "gt%d.csv" % n))
    pdf, html_ = os.path.join(d, "R%d.pdf" % n), os.path.join(d, "R%d.html" % n)
    args = ["report", "grid", inp, "--pdf", pdf, "-o", html_]
    for k, v in info:
        args += ["--info", "%s=%s" % (k, v)]
    run_long(*args[0:])
    if not open(pdf, "rb").read(5).startswith(b"%PDF"):
        fail("%s is not a PDF" % pdf)
    pages = pdf_pages(pdf)
    m = len(pages)
    rid = dict(info)["report_id"]
    for k, page in enumerate(pages, 1):
        foot = [l for l in page.splitlines() if l.strip()][-1]
        if not re.search(r"page %d of %d\s*$" % (k, m), foot) or rid not in foot:
            fail("N = %d: page %d of %d has the foot %r" % (n, k, m, foot))
    text = "\n".join(pages)
    flat = " ".join(text.split())
    for k, v in info:
        if " ".join(v.split()) not in flat:
            fail("N = %d: the PDF lacks the info value %r (%s)" % (n, v, k))
    labels = {"report_id": "Report number", "item": "Calibrated item", "customer": "Customer",
              "measured_on": "Date of measurement", "approved_by": "Approved by"}
    for label in (labels[k] for k, _ in info if k in labels):
        if label not in flat:
            fail("N = %d: the PDF lacks the label %r" % (n, label))
    if "coverage factor k = 2" not in flat or "Not included" not in flat:
        fail("N = %d: the PDF lacks the uncertainty statement" % n)
    nodes = set()
    for line in text.splitlines():
        mm = NODE_ROW.match(line)
        if mm:
            nodes.add((int(mm.group(1)), int(mm.group(2))))
    want = {(i, j) for i in range(n) for j in range(n)}
    if nodes != want:
        fail("N = %d: %d of the %d appendix rows in the PDF (missing e.g. %s)"
             % (n, len(nodes & want), n * n, sorted(want - nodes)[:5]))
    # no heading left alone at the foot of a page: the last line above the page label is not one
    heads = set()
    hp = re.compile(r"<h[23][^>]*>(.*?)</h[23]>", re.S)
    for h in hp.findall(open(html_, encoding="utf-8").read()):
        heads.add(" ".join(re.sub(r"<[^>]+>", "", h).split()))
    for k, page in enumerate(pages[:-1], 1):
        body = [l.strip() for l in page.splitlines() if l.strip()][:-1]
        if body and " ".join(body[-1].split()) in heads:
            fail("N = %d: page %d ends with the heading %r" % (n, k, body[-1]))
    return m


def case_pdf():
    d = fresh_dir("pdf")
    info = [("report_id", "CAL-2026-0042"), ("item", "XY stage S/N 4711"),
            ("customer", "ACME Präzision GmbH"), ("operator", "J. Doe"),
            ("measured_on", "2026-11-20"), ("conditions", "20.0 °C ± 0.2 K, 45 % rH"),
            ("approved_by", "Dr. A. Smith"), ("purchase_order", "PO 77/12")]
    m25 = check_grid_pdf(d, 25, info)
    m101 = check_grid_pdf(d, 101, info[:3])
    if not m101 > m25:
        fail("the N = 101 PDF has %d pages, the N = 25 one %d" % (m101, m25))
    # an info file, and its errors (exit 2, one line naming the file and line, nothing written)
    inp = os.path.join(d, "in25.csv")
    with open(os.path.join(d, "info.txt"), "w") as f:
        f.write("# the certificate's identification\nreport_id = F-1\n\nitem = stage <B>\n")
    out = os.path.join(d, "F.html")
    run("report", "grid", inp, "-o", out, "--info-file", os.path.join(d, "info.txt"),
        "--info", "item=stage C")
    c = parse(open(out, encoding="utf-8").read())
    if c.ids.get("info-report_id", (0, ""))[1] != "F-1" or c.ids.get("info-item", (0, ""))[1] != "stage C":
        fail("--info-file then --info: %r %r" % (c.ids.get("info-report_id"), c.ids.get("info-item")))
    with open(os.path.join(d, "bad.txt"), "w") as f:
        f.write("report_id = X\nno equals sign here\n")
    r = run("report", "grid", inp, "-o", os.path.join(d, "B.html"), "--info-file",
            os.path.join(d, "bad.txt"), expect=2)
    if "bad.txt:2:" not in r.stderr or os.path.exists(os.path.join(d, "B.html")):
        fail("a bad --info-file: %r" % r.stderr)
    run("report", "grid", inp, "-o", os.path.join(d, "B.html"), "--info", "novalue", expect=2)
    # an --info-file that is a folder is named as such (the shared input opener), nothing written
    r = run("report", "grid", inp, "-o", os.path.join(d, "B.html"), "--info-file", d, expect=2)
    if "is a directory" not in r.stderr or os.path.exists(os.path.join(d, "B.html")):
        fail("an --info-file that is a folder: %r" % r.stderr)
    # --pdf without Chromium: says so, exit 1, nothing written
    env = dict(os.environ, PATH="/nonexistent")
    env.pop("SELFCAL_CHROMIUM", None)
    p = subprocess.run([CLI, "report", "grid", inp, "-o", os.path.join(d, "N.html"), "--pdf",
                        os.path.join(d, "N.pdf")], capture_output=True, text=True, env=env,
                       timeout=300)
    if p.returncode != 1 or "Chromium" not in p.stderr or os.path.exists(os.path.join(d, "N.pdf")) \
            or os.path.exists(os.path.join(d, "N.html")):
        fail("--pdf without Chromium: exit %d, %r" % (p.returncode, p.stderr))
    # the profile report prints too, with its own label
    run("simulate", "profile", "--n", 200, "--d1", 10, "--d2", 11, "--out", os.path.join(d, "p.csv"),
        "--truth", os.path.join(d, "pt.csv"))
    run_long("report", "profile", os.path.join(d, "p.csv"), "--pdf", os.path.join(d, "P.pdf"),
             "--info", "report_id=P-9")
    pages = pdf_pages(os.path.join(d, "P.pdf"))
    for k, page in enumerate(pages, 1):
        if not re.search(r"P-9.*page %d of %d\s*$" % (k, len(pages)), page.rstrip()):
            fail("profile PDF: page %d lacks its label" % k)
    if [x for x in os.listdir(d) if x.startswith(".selfcal-report")]:
        fail("--pdf left its temporary HTML file")


def expect_bad(args, name, outs):
    p = run(*args, expect=2)
    lines = p.stderr.strip().splitlines()
    if len(lines) != 1 or not re.match(r"selfcal: .*%s(:\d+)?: " % re.escape(name), lines[0]):
        fail("%s: want one line 'selfcal: %s:LINE: ...', got %r" % (" ".join(map(str, args)), name, p.stderr))
    for o in outs:
        if os.path.exists(o):
            fail("%s left %s behind" % (" ".join(map(str, args)), o))
    for f in os.listdir(os.path.dirname(outs[0])):
        if ".tmp" in f or f.startswith(".") and "R." in f:
            fail("temporary file left: %s" % f)


def case_bad_input():
    d = fresh_dir("bad_input")
    p = lambda x: os.path.join(d, x)  # noqa: E731
    inp, _, _ = simulate_grid(d, n=9, plan="ye")
    out = p("R.html")
    lines = open(inp).read().splitlines()
    bad = p("bad.csv")
    lines[12] = lines[12].split(",")[0] + ",1,1,zz,0"
    open(bad, "w").write("\n".join(lines) + "\n")
    expect_bad(["report", "grid", bad, "-o", out], "bad.csv", [out])
    expect_bad(["report", "grid", p("missing.csv"), "-o", out], "missing.csv", [out])
    # a plan that does not identify G, and a method whose views are missing
    hdr = [l for l in open(inp).read().splitlines() if l.startswith("#") and "view 2" not in l]
    rows = [l for l in open(inp).read().splitlines()
            if not l.startswith("#") and not l.startswith("view") and not l.startswith("2,")]
    open(p("two.csv"), "w").write("\n".join(hdr + ["view,i,j,x_mm,y_mm"] + rows) + "\n")
    expect_bad(["report", "grid", p("two.csv"), "-o", out], "two.csv", [out])
    expect_bad(["report", "grid", p("two.csv"), "-o", out, "--method", "ye"], "two.csv", [out])
    pin = p("p.csv")
    run("simulate", "profile", "--out", pin, "--truth", p("pt.csv"))
    pl = open(pin).read().splitlines()
    pl[20] = "1,999999,0,0,0"
    open(p("pbad.csv"), "w").write("\n".join(pl) + "\n")
    expect_bad(["report", "profile", p("pbad.csv"), "-o", out], "pbad.csv", [out])
    # verify: bad table, bad plate error file
    open(p("junk.lut"), "wb").write(b"not a table at all" * 10)
    run("grid", "--method", "lsq", inp, "--map", p("G.csv"), "--artifact", p("A.csv"))
    run("lut", "build", "--map", p("G.csv"), "-o", p("t.lut"))
    expect_bad(["verify", inp, "--table", p("junk.lut"), "--artifact", p("A.csv"), "--tolerance-um", 1,
                "--residuals", p("r.csv"), "--html", out], "junk.lut", [out, p("r.csv")])
    open(p("Abad.csv"), "w").write("i,j,ax_um,ay_um\n0,0,1,\n")
    expect_bad(["verify", inp, "--table", p("t.lut"), "--artifact", p("Abad.csv"), "--tolerance-um", 1,
                "--html", out], "Abad.csv", [out])
    expect_bad(["report", "grid", inp, "-o", out, "--verify", p("two.csv"), "--table", p("junk.lut")],
               "junk.lut", [out])
    # usage errors are exit 2 as well
    run("report", "grid", inp, expect=2)
    run("report", "grid", inp, "-o", out, "--method", "fourier", expect=2)
    run("verify", inp, "--table", p("t.lut"), expect=2)
    if os.path.exists(out):
        fail("usage errors left a report")


def svg_texts(path):
    root = ET.parse(path).getroot()
    ns = "{http://www.w3.org/2000/svg}"
    return root, ns, [t for t in root.iter(ns + "text")]


def check_texts_inside(path):
    """No text of the SVG runs past its edges (colour-bar labels were cut at the right edge): each
    text's extent, from its anchor and an upper bound of its width (0.62 em a character), lies
    within the drawing; texts in rotated groups (axis titles) are skipped."""
    root = ET.parse(path).getroot()
    ns = "{http://www.w3.org/2000/svg}"
    width = float(root.get("width"))
    rotated = {id(t) for g in root.iter(ns + "g") if "rotate" in (g.get("transform") or "")
               for t in g.iter(ns + "text")}
    for t in root.iter(ns + "text"):
        if id(t) in rotated or not t.text:
            continue
        x, size = float(t.get("x")), float(t.get("font-size", 12))
        w = 0.62 * size * len(t.text)
        anchor = t.get("text-anchor", "start")
        lo = x - (w if anchor == "end" else w / 2 if anchor == "middle" else 0)
        hi = x + (0 if anchor == "end" else w / 2 if anchor == "middle" else w)
        if lo < -1 or hi > width + 1:
            fail("%s: the text %r runs from %.0f to %.0f px, the drawing is %.0f wide"
                 % (path, t.text, lo, hi, width))


def case_plots():
    d = fresh_dir("plots")
    p = lambda x: os.path.join(d, x)  # noqa: E731
    n = 9
    inp, gt, at = simulate_grid(d, n=n, plan="ye", seed=11)
    run("grid", "--method", "lsq", inp, "--map", p("G.csv"), "--artifact", p("A.csv"))
    # the plate error file is drawn (it used to be refused), against its truth too
    run("plot", "map", p("A.csv"), "-o", p("A.svg"), "--pitch-mm", 1)
    run("plot", "map", p("A.csv"), "-o", p("A2.svg"), "--truth", at)
    root, ns, texts = svg_texts(p("A.svg"))
    alltext = " ".join(t.text or "" for t in texts)
    if "plate" not in alltext.lower() or len(root.findall(ns + "polygon")) < n * n * 0.9:
        fail("plate error plot: %s" % alltext[:300])
    # arrows stay inside the frame: every arrow head inside the plot rectangle
    run("plot", "map", p("G.csv"), "-o", p("G.svg"))
    root, ns, texts = svg_texts(p("G.svg"))
    frames = [r for r in root.iter(ns + "rect") if r.get("fill") == "none" and r.get("stroke") == "#333"]
    fx, fy = float(frames[0].get("x")), float(frames[0].get("y"))
    fw, fh = float(frames[0].get("width")), float(frames[0].get("height"))
    heads = 0
    for poly in root.iter(ns + "polygon"):
        pts = [tuple(map(float, q.split(","))) for q in poly.get("points").split()]
        if all(fx - 1 <= x <= fx + fw + 1 and fy - 1 <= y <= fy + fh + 1 for x, y in pts):
            heads += 1
        elif pts[0][1] < fy + fh + 30:  # not the scale bar below the frame
            fail("an arrow head outside the frame: %s (frame %g,%g %gx%g)" % (pts, fx, fy, fw, fh))
    if heads < n * n * 0.9:
        fail("%d arrow heads inside the frame" % heads)
    # u(G) as a colour map (cells) instead of ellipses, the worst node in mm
    cells = [r for r in root.iter(ns + "rect") if r.get("fill", "").startswith("#") and r.get("fill") != "#333"]
    if len(cells) < n * n or root.findall(ns + "ellipse"):
        fail("u map: %d cells, %d ellipses" % (len(cells), len(root.findall(ns + "ellipse"))))
    alltext = " ".join(t.text or "" for t in texts)
    if not re.search(r"max \|G\| = [0-9.e+-]+ µm at \(-?[0-9.]+, -?[0-9.]+\) mm", alltext):
        fail("worst node not named in mm: %s" % alltext[:400])
    # a long absolute path in the title is shortened to fit the drawing
    longdir = os.path.join(d, "a_very_long_directory_name_that_goes_on_and_on" * 3)
    os.makedirs(longdir, exist_ok=True)
    longin = os.path.join(longdir, "measurement_with_a_long_name.csv")
    shutil.copy(inp, longin)
    run("grid", "--method", "lsq", longin, "--map", p("G2.csv"), "--plot", p("long.svg"))
    root, ns, texts = svg_texts(p("long.svg"))
    width = float(root.get("width"))
    rotated = {id(t) for g in root.iter(ns + "g") if g.get("transform") for t in g.iter(ns + "text")}
    for t in texts:
        if id(t) in rotated:  # axis labels turned by 90 degrees: their x is not their extent
            continue
        size = float(t.get("font-size"))
        est = sum(0.72 if c.isupper() else 0.58 for c in (t.text or "")) * size
        x, anchor = float(t.get("x")), t.get("text-anchor")
        left = x - est / 2 if anchor == "middle" else x - est if anchor == "end" else x
        if left < -2 or left + est > width + 2:
            fail("text runs off the drawing (width %g): %r at x=%g size %g" % (width, t.text, x, size))
    if os.path.dirname(longin) in " ".join(t.text or "" for t in texts):
        fail("the title holds the absolute path")
    # plot xy (scripts/figs-grid.sh): a logarithmic x axis labelled in decades, one line per column
    with open(p("xy.csv"), "w") as f:
        f.write("sigma_r_um,ye,lsq\n0.001,1.2,0.9\n0.01,1.25,0.92\n0.1,1.22,\n1,1.3,0.95\n")
    run("plot", "xy", p("xy.csv"), "-o", p("xy.svg"), "--logx", "--title", "t")
    root, ns, texts = svg_texts(p("xy.svg"))
    labels = [t.text for t in texts]
    if not all(x in labels for x in ("0.001", "0.01", "0.1", "1", "ye", "lsq")):
        fail("plot xy labels: %s" % labels)
    lines = root.findall(ns + "polyline")
    if len(lines) != 3:  # ye, and lsq broken at its gap
        fail("plot xy: %d polylines" % len(lines))
    # every axis has a title: the y axis, without --ylabel, names the series' columns
    ytitles = [t.text for g in root.iter(ns + "g") if "rotate(-90)" in (g.get("transform") or "")
               for t in g.iter(ns + "text")]
    if ytitles != ["ye, lsq"] or "sigma_r_um" not in labels:
        fail("plot xy axis titles: y %r, x in %s" % (ytitles, labels))
    run("plot", "xy", p("xy.csv"), "-o", p("xy2.svg"), "--y", "nope", expect=2)
    # a large map (151 x 151 nodes) is drawn at one node in six each way over |G|, always with
    # its largest arrow; its |G| and u(G) cells in blocks of 2 x 2 nodes
    n = 151
    with open(p("big.csv"), "w") as f:
        f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
        for i in range(n):
            for j in range(n):
                gx = 5.0 if (i, j) == (61, 62) else 0.3 * math.sin(i / 7.0)
                u = 0.9 if (i, j) == (100, 101) else 0.1
                f.write("%d,%d,%g,%g,%g,%g,%g,%g\n" % (i, j, j - 75, i - 75, gx, 0.2, u, u))
    run("plot", "map", p("big.csv"), "-o", p("big.svg"))
    root, ns, texts = svg_texts(p("big.svg"))
    arrows = [a for a in root.iter(ns + "line") if a.get("stroke") == "#1f4e9c"]
    # above 41 nodes a side: |G| as a colour map under arrows at one node in ceil(N / 26) = 6
    if not 26 * 26 <= len(arrows) <= 26 * 26 + 2:  # 26 x 26 nodes, the largest, the scale bar
        fail("large map: %d arrows" % len(arrows))
    alltext = " ".join(t.text or "" for t in texts)
    if "|G| (µm)" not in alltext or "colour: |G| at every node" not in alltext:
        fail("large map: no |G| colour map under the arrows: %s" % alltext[:400])
    if "one node in 6" not in alltext or "max |G| = 5" not in alltext:
        fail("large map texts: %s" % alltext[:400])
    # the largest arrow (5 µm at node (61, 62), off the drawn nodes) is drawn: longer than 3 times
    # any other but the scale bar
    bar = max(arrows, key=lambda a: float(a.get("y1")))  # the scale bar, below the frame
    lens = sorted(math.hypot(float(a.get("x2")) - float(a.get("x1")), float(a.get("y2")) - float(a.get("y1")))
                  for a in arrows if a is not bar)
    if not lens[-1] > 3 * lens[-3]:
        fail("large map: the largest arrow is not drawn (%s)" % lens[-4:])
    cells = [r for r in root.iter(ns + "rect") if r.get("fill", "").startswith("#") and r.get("fill") != "#333"]
    # two colour maps (|G| under the arrows, u(G)) of 76 x 76 cells, and their bars' 64 steps
    if not 2 * 76 * 76 <= len(cells) <= 2 * 76 * 76 + 200 or os.path.getsize(p("big.svg")) > 2_000_000:
        fail("large map: %d cells, %d bytes" % (len(cells), os.path.getsize(p("big.svg"))))
    check_texts_inside(p("big.svg"))
    # the colour bars of the standalone maps are not cut: a map with u(G), and with its truth
    ug = p("small_u.csv")
    with open(ug, "w") as f:
        f.write("i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n")
        for i in range(9):
            for j in range(9):
                f.write("%d,%d,%g,%g,%g,%g,%g,%g\n" % (i, j, j, i, 1e-4 * i, -2e-4 * j,
                                                       1e-5 * (1 + i * j), 1e-5))
    run("plot", "map", ug, "-o", p("small_u.svg"))
    check_texts_inside(p("small_u.svg"))
    run("plot", "map", ug, "-o", p("small_ut.svg"), "--truth", ug)
    check_texts_inside(p("small_ut.svg"))
    # profile plot: the f chart has uncertainty bands
    pin, pout = p("p.csv"), p("P.csv")
    run("simulate", "profile", "--out", pin, "--truth", p("pt.csv"))
    run("profile", "--method", "lsq", pin, "--out", pout, "--plot", p("p.svg"), "--quiet")
    root = ET.parse(p("p.svg")).getroot()
    bands = [q for q in root.iter("{http://www.w3.org/2000/svg}polygon") if q.get("fill-opacity")]
    if len(bands) < 2:
        fail("profile plot has %d uncertainty bands" % len(bands))


def case_figs_grid():
    """scripts/figs-grid.sh with 1 trial: the figure CSVs hold every method and the charts parse."""
    script, bench = sys.argv[4], sys.argv[5]
    d = fresh_dir("figs_grid")
    env = dict(os.environ, SELFCAL=CLI, BENCH=bench, OUT=d, TRIALS="1")
    p = subprocess.run(["sh", script], capture_output=True, text=True, timeout=280, env=env)
    if p.returncode != 0:
        fail("figs-grid.sh: exit %d\n%s\n%s" % (p.returncode, p.stdout[-2000:], p.stderr[-2000:]))
    methods = ["ye", "double-shift", "lsq (Ye views)", "lsq (Petro views)"]
    for name, nrows in (("fig4_sr_N25", 4), ("fig4_sg", 3), ("fig5", 4)):
        with open(os.path.join(d, name + ".csv")) as f:
            rows = list(csv.reader(f))
        if rows[0][1:5] != methods or len(rows) != nrows + 1:
            fail("%s.csv: %s" % (name, rows[:2]))
        for r in rows[1:]:
            vals = [float(x) for x in r[1:] if x]
            if len(vals) < 4 or not all(0.3 < v < 3 for v in vals):
                fail("%s.csv: implausible sigma_C/sigma_r row %s" % (name, r))
        root = ET.parse(os.path.join(d, name + ".svg")).getroot()
        if len(root.findall("{http://www.w3.org/2000/svg}polyline")) < 4:
            fail("%s.svg: fewer than 4 lines" % name)
    with open(os.path.join(d, "fig5.csv")) as f:
        head = next(csv.reader(f))
    if "lsq (Petro views) predicted" not in head:
        fail("fig5.csv lacks the prediction: %s" % head)


{"figs_grid": case_figs_grid, "outliers": case_outliers, "stage": case_stage, "render_grid": case_render_grid, "render_profile": case_render_profile,
 "numbers_grid": case_numbers_grid, "numbers_profile": case_numbers_profile,
 "pdf": case_pdf, "verify": case_verify, "verify_guarded": case_verify_guarded, "bad_input": case_bad_input, "plots": case_plots,
 "pipes": case_pipes}[CASE]()
print("ok")
