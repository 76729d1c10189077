#!/usr/bin/env python3
"""Seeded mutation fuzzing of every file the selfcal command line reads (except the grid input,
fuzzed by grid_cli_test.py): profile inputs, maps, profile results, tables.

usage: fuzz_cli.py CLI TARGET [--iterations N] [--seed S] [--work DIR] [--repro-dir DIR]
TARGET: profile | lut-build | lut-table | export | plot
"""
import os
import re
import struct
import sys
import zlib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fuzzlib  # noqa: E402

ap = fuzzlib.base_args(__doc__)
ap.add_argument("cli")
ap.add_argument("target", choices=["profile", "lut-build", "lut-table", "export", "plot"])
A = ap.parse_args()
SKIP = fuzzlib.skip_known(A)
F = fuzzlib.Fuzz(A, "fuzz-" + A.target)
CLI = A.cli
W = F.work
rnd = F.rnd


def must(cmd):
    rc, out, err = F.run(cmd, timeout=120)
    if rc != 0:
        print("setup failed: %s\n%s" % (" ".join(cmd), err.decode()), file=sys.stderr)
        sys.exit(1)


def p(name):
    return os.path.join(W, name)


# ---- valid inputs, made by the product -------------------------------------------------------
def make_profiles():
    bases = []
    for tag, n, d1, d2, extra in (("a", 70, 5, 7, []), ("b", 330, 10, 11, []),
                                  ("c", 48, 3, 4, ["--no-sigma-lines"]), ("d", 35, 5, 7, [])):
        must([CLI, "simulate", "profile", "--n", str(n), "--d1", str(d1), "--d2", str(d2),
              "--out", p("prof_%s.csv" % tag), "--truth", p("truth_%s.csv" % tag), "--seed", "3"]
             + extra)
        bases.append(p("prof_%s.csv" % tag))
    return bases


def make_maps():
    maps = []
    for tag, n, plan in (("a", 5, "ye"), ("b", 9, "double-shift")):
        must([CLI, "simulate", "grid", "--plan", plan, "--n", str(n), "--pitch-mm", "1.5",
              "--out", p("grid_%s.csv" % tag), "--truth-map", p("gtrue_%s.csv" % tag)])
        must([CLI, "grid", "--method", "lsq" if tag == "b" else plan, p("grid_%s.csv" % tag),
              "--map", p("map_%s.csv" % tag)])
        maps.append(p("map_%s.csv" % tag))
    return maps


def make_results(profiles):
    res = []
    for k, pr in enumerate(profiles[:2]):
        out = p("res_%d.csv" % k)
        must([CLI, "profile", "--method", "lsq", pr, "--out", out])
        res.append(out)
    return res


# ---- format-specific header mutations --------------------------------------------------------
def nums(rnd, n):
    return rnd.choice(["0", "1", "2", "3", "-1", "-7", str(n), str(n - 1), str(n + 1), str(2 * n),
                       str(n // 2), "100000000", "100000001", "2147483647", "2147483648",
                       "-2147483648", "9223372036854775807", "99999999999999999999", "1e3", "5.5",
                       "", "x", "nan", "inf", "0x20", " 12 ", "+9"])


def reals(rnd):
    if SKIP:
        return rnd.choice(["0", "-1", "1e-300", "1e309", "nan", "inf", "-inf", "", "0.001",
                           "1000000", "4.9e-324", "-0", "abc", "1,2", "2.5", "1e-12"])
    return rnd.choice(["0", "-1", "1e-300", "1e300", "1e308", "1e309", "nan", "inf", "-inf", "",
                       "0.001", "1000000", "4.9e-324", "-0", "abc", "1,2", "2.5", "1e-12"])


def prof_N(rnd, lines):
    return fuzzlib.set_header(lines, rb"#\s*N\s*=", b"# N = " + nums(rnd, 70).encode() + b"\n")


def prof_s(rnd, lines):
    return fuzzlib.set_header(lines, rb"#\s*s_mm\s*=", b"# s_mm = " + reals(rnd).encode() + b"\n")


def prof_d(rnd, lines):
    k = rnd.choice(("1", "2"))
    kk = rnd.choice((k, k, k, "3", "0", "-1", "01", "1 2", ""))
    new = ("# scan %s: d=%s\n" % (kk, nums(rnd, 7))).encode()
    if rnd.random() < 0.2:
        new = rnd.choice((b"# scan 1 d=5\n", b"# scan 1: d=\n", b"# scan 1: e=5\n",
                          b"# scan: d=5\n", b"#scan 2:d=7\n", b"# scan 2: d = 7 8\n",
                          b"# scan 1: d=5 # c\n"))
    return fuzzlib.set_header(lines, (r"#\s*scan\s+%s" % k).encode(), new)


def prof_sigma(rnd, lines):
    key = rnd.choice((b"sigma_disp_um", b"sigma_angle_urad"))
    new = b"# " + key + b" = " + reals(rnd).encode() + b"\n"
    if rnd.random() < 0.3:  # duplicated
        lines.insert(1, new)
        return lines
    return fuzzlib.set_header(lines, rb"#\s*" + key, new)


def prof_magic(rnd, lines):
    lines[0] = rnd.choice((b"# selfcal-profile v2\n", b"# selfcal-grid v1\n", b"selfcal-profile v1\n",
                           b"#selfcal-profile v1\n", b"# selfcal-profile v1 \r\n", b"\xef\xbb\xbf# selfcal-profile v1\n",
                           b"  # selfcal-profile v1\n"))
    return lines


def prof_colhdr(rnd, lines):
    return fuzzlib.set_header(lines, rb"scan,n", rnd.choice((
        b"scan,n,m1_um,m2_um\n", b"scan,n,m1_um,m2_um,m3_urad,extra\n", b"n,scan,m1_um,m2_um,m3_urad\n",
        b"scan, n, m1_um, m2_um, m3_urad\n", b"SCAN,N,M1_UM,M2_UM,M3_URAD\n")))


PROFILE_OPS = (prof_N, prof_N, prof_s, prof_d, prof_d, prof_sigma, prof_magic, prof_colhdr)


def map_ops():
    def header(rnd, lines):
        lines[0] = rnd.choice((b"i,j,x_mm,y_mm,gx_um,gy_um\n", b"i,j,x_mm,y_mm,gx_um\n",
                               b"j,i,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n",
                               b"i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um,extra\n",
                               b"# comment\n" + lines[0], b"\n" + lines[0]))
        return lines

    def index(rnd, lines):  # a node index moved (gap, repeat, far away)
        k = rnd.randrange(1, len(lines)) if len(lines) > 1 else 0
        f = lines[k].split(b",")
        if len(f) > 2:
            f[rnd.randrange(2)] = rnd.choice((b"0", b"1", b"100", b"101", b"-1", b"4", b"8",
                                             b"9", b"10", b"99999999999"))
        lines[k] = b",".join(f)
        return lines

    def constant(rnd, lines):  # every x or every y the same (zero pitch), or reversed
        col = rnd.choice((2, 3))
        mode = rnd.randrange(2 if SKIP else 3)
        out = [lines[0]]
        for ln in lines[1:]:
            f = ln.rstrip(b"\n").split(b",")
            if len(f) > col:
                try:
                    v = float(f[col])
                    f[col] = (b"0" if mode == 0 else repr(-v).encode() if mode == 1
                              else repr(v * 1e12).encode())
                except ValueError:
                    pass
            out.append(b",".join(f) + b"\n")
        return out
    return (header, index, index, constant)


def result_ops():
    def header(rnd, lines):
        lines[0] = rnd.choice((b"n,x_mm,f_um,uf_um\n", b"n,x_mm,ey_um\n", b"x_mm,n,f_um,uf_um,ey_um\n",
                               b"n,x_mm,f_um,uf_um,ey_um,extra\n", b"n,f_um\n"))
        return lines

    def empty_cells(rnd, lines):  # ey_um emptied somewhere (only trailing cells may be empty)
        k = rnd.randrange(1, len(lines)) if len(lines) > 1 else 0
        f = lines[k].rstrip(b"\n").split(b",")
        f[rnd.randrange(len(f))] = b""
        lines[k] = b",".join(f) + b"\n"
        return lines

    def long_profile(rnd, lines):  # more points than a table can hold
        n = rnd.choice((2047, 2048, 2049, 5000))
        return [b"n,x_mm,f_um,uf_um,ey_um\n"] + [b"%d,%d,0,0,%g\n" % (i, i, (i % 7) * 0.1)
                                                   for i in range(n)]
    return (header, empty_cells, empty_cells, long_profile)


def write(path, data):
    with open(path, "wb") as fh:
        fh.write(data)


# ---- targets -----------------------------------------------------------------------------
def map_corpus():
    """The valid stage maps and profile results the map and table targets mutate, and their
    mutation operators: (maps, results, map operators, result operators)."""
    maps = [open(m, "rb").read() for m in make_maps()]
    results = [open(r, "rb").read() for r in make_results(make_profiles())]
    return maps, results, map_ops(), result_ops()


def remove(*paths):
    """Each path that exists, removed (a case's inputs and outputs before the next)."""
    for f in paths:
        if os.path.exists(f):
            os.unlink(f)


def t_profile():
    bases = [open(b, "rb").read() for b in make_profiles()]
    for t in range(A.iterations):
        src = fuzzlib.mutate_text(rnd, rnd.choice(bases), PROFILE_OPS)
        inp = p("in_%d.csv" % t)
        write(inp, src)
        out, svg = p("out_%d.csv" % t), p("out_%d.svg" % t)
        method = rnd.choice(("dft", "lsq"))
        cmd = [CLI, "profile", "--method", method, inp, "--out", out]
        outs = [out]
        if rnd.random() < 0.3:
            cmd += ["--plot", svg]
            outs.append(svg)
        if rnd.random() < 0.1:
            cmd += ["--mc", "3", "--seed", "1"]
        rc = F.check(cmd, [inp], outs, "profile-" + method, expect_file=inp)
        if rc == 0:  # chain: the result goes on to plot profile and lut build
            F.check([CLI, "plot", "profile", out, "-o", svg], [inp, out], [svg], "plot-profile-chain",
                    expect_file=out)
        remove(inp, out, svg)


def t_lut_build():
    maps, results, mops, rops = map_corpus()
    for t in range(A.iterations):
        m, pr = p("map_in_%d.csv" % t), p("prof_in_%d.csv" % t)
        out = p("table_%d.lut" % t)
        which = rnd.randrange(3)  # 0 map only, 1 profile only, 2 both mutated
        write(m, fuzzlib.mutate_text(rnd, rnd.choice(maps), mops) if which != 1 else rnd.choice(maps))
        write(pr, fuzzlib.mutate_text(rnd, rnd.choice(results), rops) if which != 0
              else rnd.choice(results))
        cmd = [CLI, "lut", "build", "--map", m, "-o", out]
        if which or rnd.random() < 0.5:
            cmd += ["--profile", rnd.choice(("x:y:", "y:x:", "x:z:", "z:y:")) + pr]
        if rnd.random() < 0.2:
            cmd += ["--encoding", rnd.choice(("int16", "int32"))]
        rc = F.check(cmd, [m, pr], [out], "lut-build", expect_file=None)
        if rc == 2:
            err = F.run(cmd)[2].decode("utf-8", "replace")
            if m not in err and pr not in err:
                F.soft(err.strip()[:100])
        if rc == 0:
            F.check([CLI, "lut", "dump", out], [out], [], "lut-dump-chain", rc_ok=(0,))
            F.check([CLI, "lut", "info", out], [out], [], "lut-info-chain", rc_ok=(0,))
        remove(m, pr, out)


def fix_table(b):
    """Make a mutated table consistent again: size field and CRC-32, so it reaches the range
    checks (a plain mutation is caught by the size, magic, version or CRC check)."""
    b = bytearray(b)
    if len(b) < 20:
        return bytes(b)
    b[12:16] = struct.pack("<I", len(b))
    crc = zlib.crc32(bytes(b[:-4])) & 0xFFFFFFFF
    b[-4:] = struct.pack("<I", crc)
    return bytes(b)


def t_lut_table():
    maps = make_maps()
    res = make_results(make_profiles())
    tables = []
    for k, (mp, args) in enumerate(((maps[0], []), (maps[1], ["--profile", "x:y:" + res[0],
                                                               "--profile", "y:x:" + res[1]]),
                                    (maps[1], ["--encoding", "int32", "--profile", "z:x:" + res[1]]))):
        out = p("base_%d.lut" % k)
        must([CLI, "lut", "build", "--map", mp, "-o", out, "--created", "1700000000"] + args)
        tables.append(open(out, "rb").read())
    interesting = [0, 1, 2, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF]
    for t in range(A.iterations):
        b = bytearray(rnd.choice(tables))
        c = rnd.randrange(7)
        for _ in range(rnd.choice((1, 1, 2, 4))):
            i = rnd.randrange(len(b))
            if c == 0:
                b[i] ^= 1 << rnd.randrange(8)
            elif c == 1:
                b[i] = rnd.randrange(256)
            elif c == 2:  # header field to an interesting value (u16 / f64 / u32)
                off = rnd.choice((8, 10, 12, 16, 18, 20, 21, 22, 24, 32, 40, 48, 56, 60))
                if off in (24, 32, 40, 48):
                    v = rnd.choice((0.0, -0.0, 1e-300, -1.0, 1e6, 1e7, 1e300, float("inf"),
                                    float("nan"), 1e-7, 1e-6))
                    b[off:off + 8] = struct.pack("<d", v)
                elif off in (12, 56, 60):
                    b[off:off + 4] = struct.pack("<I", rnd.choice((0, 1, 3, 1000000000,
                                                                    1000000001, 0xFFFFFFFF)))
                elif off in (20, 21):
                    b[off] = rnd.choice((0, 1, 2, 3, 8, 9, 255))
                else:
                    b[off:off + 2] = struct.pack("<H", rnd.choice(interesting))
            elif c == 3:
                b = b[: rnd.randrange(len(b) + 1)]
                break
            elif c == 4:  # bytes appended
                b += bytes(rnd.randrange(256) for _ in range(rnd.randrange(1, 64)))
                break
            elif c == 5:
                b = bytearray(rnd.randrange(256) for _ in range(rnd.randrange(0, 3000)))
                break
            else:  # a 16/32-bit field anywhere to an extreme
                j = rnd.randrange(max(1, len(b) - 4))
                b[j:j + 2] = struct.pack("<H", rnd.choice(interesting))
        data = bytes(b)
        if rnd.random() < 0.7:
            data = fix_table(data)
        tab = p("t_%d.lut" % t)
        write(tab, data)
        for sub in ("dump", "info"):
            F.check([CLI, "lut", sub, tab], [tab], [], "lut-" + sub, expect_file=tab)
        os.unlink(tab)


def profile_option(rnd, results, rops, t):
    """A --profile AXIS:DIR:RESULT[@OFFSET_MM] for the table formats that take straightness
    (Beckhoff cross lists, Siemens CEC tables, Automation1 1-D tables), sometimes with --travel / --profile-interval;
    the result file is valid or mutated. Returns (options, the result file)."""
    r = p("res_in_%d.csv" % t)
    write(r, rnd.choice(results) if rnd.random() < 0.5 else
          fuzzlib.mutate_text(rnd, rnd.choice(results), rops))
    axis, d = rnd.choice((("x", "y"), ("y", "x"), ("x", "y"), ("y", "x"), ("x", "z"), ("y", "y"),
                          ("z", "x")))
    spec = "%s:%s:%s" % (axis, d, r) + rnd.choice(("", "", "", "@0", "@-3", "@-100", "@1e9", "@x",
                                                   "@nan", "@"))
    opts = ["--profile", spec]
    if rnd.random() < 0.4:
        opts += ["--travel", rnd.choice(("-200,400", axis + ":-200,400", "400,-200", "0,1",
                                         "z:-1,1", "-1e9,1e9", "nan,1", ",", "-200"))]
    if rnd.random() < 0.3:
        opts += ["--profile-interval", rnd.choice(("0.5", "1", "0.00001", "1000", "0", "-1",
                                                   "nan"))]
    return opts, r


def t_export():
    maps, results, mops, rops = map_corpus()
    for t in range(A.iterations):
        fmt = rnd.choice(("beckhoff", "siemens-cec", "linuxcnc", "kmotion", "klipper", "marlin",
                          "reprap", "aerotech-a1", "powerpmac"))
        with_profile = fmt in ("beckhoff", "siemens-cec", "aerotech-a1") and rnd.random() < 0.4
        m = p("map_in_%d.csv" % t)
        # with a profile, the map is often left valid so that the profile's own paths are reached
        write(m, rnd.choice(maps) if with_profile and rnd.random() < 0.6 else
              fuzzlib.mutate_text(rnd, rnd.choice(maps), mops))
        out = p("exp_%d.txt" % t)
        # every file an export may write: OUT, OUT-x/-y (--axis both), OUT-cross-DIR (Beckhoff's
        # profiles), OUT-1d (Automation1's)
        outs = [out] + [p("exp_%d-%s.txt" % (t, s))
                        for s in ("x", "y", "cross-x", "cross-y", "cross-z", "1d")]
        ins = [m]
        cmd = [CLI, "export", "--format", fmt, "--map", m, "-o", out]
        if fmt in ("beckhoff", "linuxcnc") or (fmt == "siemens-cec" and rnd.random() < 0.3):
            cmd += ["--axis", rnd.choice(("x", "y")) if fmt != "siemens-cec" else "both"]
        if rnd.random() < 0.3:
            cmd += [rnd.choice(("--interval", "--at", "--limit-um")),
                    rnd.choice(("0.5", "1", "0.001", "1e-9", "1000", "-1", "0", "nan")
                               + (() if SKIP else ("1e300",)))]
        if with_profile:
            opts, r = profile_option(rnd, results, rops, t)
            cmd += opts
            ins.append(r)
        rc = F.check(cmd, ins, outs, "export-" + fmt + ("-profile" if len(ins) > 1 else ""))
        if rc == 2:
            err = F.run(cmd)[2].decode("utf-8", "replace")
            if not any(i in err for i in ins) and not err.startswith("selfcal export:"):
                F.soft(err.strip()[:100])
        remove(*(ins + outs))


def t_plot():
    maps, results, mops, rops = map_corpus()
    for t in range(A.iterations):
        svg = p("plot_%d.svg" % t)
        if rnd.random() < 0.5:
            m = p("map_in_%d.csv" % t)
            write(m, fuzzlib.mutate_text(rnd, rnd.choice(maps), mops))
            cmd = [CLI, "plot", "map", m, "-o", svg]
            ins = [m]
            if rnd.random() < 0.3:
                tr = p("truth_in_%d.csv" % t)
                write(tr, rnd.choice(maps) if rnd.random() < 0.5 else
                      fuzzlib.mutate_text(rnd, rnd.choice(maps), mops))
                cmd += ["--truth", tr]
                ins.append(tr)
            label = "plot-map"
        else:
            m = p("res_in_%d.csv" % t)
            write(m, fuzzlib.mutate_text(rnd, rnd.choice(results), rops))
            cmd = [CLI, "plot", "profile", m, "-o", svg]
            ins = [m]
            if rnd.random() < 0.3:
                tr = p("truth_in_%d.csv" % t)
                write(tr, fuzzlib.mutate_text(rnd, rnd.choice(results), rops))
                cmd += [rnd.choice(("--truth", "--compare")), tr]
                ins.append(tr)
            label = "plot-profile"
        rc = F.check(cmd, ins, [svg], label)
        if rc == 2:
            err = F.run(cmd)[2].decode("utf-8", "replace")
            if not any(i in err for i in ins):
                F.soft(re.sub(r"\d+", "#", err.strip())[:100])
        if rc == 0:
            import xml.etree.ElementTree as ET
            try:
                ET.parse(svg)
            except ET.ParseError as e:
                F.fail("output", "%s: exit 0 but the SVG is not well-formed XML: %s" % (label, e),
                       cmd, "", ins + [svg])
        remove(*(ins + [svg]))


{"profile": t_profile, "lut-build": t_lut_build, "lut-table": t_lut_table, "export": t_export,
 "plot": t_plot}[A.target]()
F.finish()
