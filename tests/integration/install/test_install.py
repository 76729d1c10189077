#!/usr/bin/env python3
"""The installed product, as a user gets it (Python 3 standard library only).

usage: test_install.py CASE BUILD_DIR SOURCE_DIR WORK_DIR VERSION [CFLAGS...]
  install  `cmake --install` into a temporary prefix, then move the prefix (the programs must still
           run without LD_LIBRARY_PATH: RPATH $ORIGIN); check the layout (SPEC §6: programs, shared
           + static library, headers, selfcal.pc, CMake package, man pages, systemd unit with the
           installed paths, example configuration); check that libselfcal.so exports exactly the
           SC_API functions of the installed headers; build examples/ with its Makefile
           (pkg-config) and with its CMakeLists (find_package(selfcal)), shared and static, and run
           them on a measurement made by the installed CLI: the node and its uncertainty must be
           those of the CLI's map.
           The daemon's components at a custom prefix pass systemd-analyze verify.
  deb      `cpack -G DEB;TGZ` from the build: one package per component (libselfcal0.<minor>,
           libselfcal-dev, selfcal, selfcald, selfcal-linuxcnc), each checked for its contents,
           dependencies and control files; all unpacked with dpkg-deb -x into one scratch root,
           where the CLI and the daemon run; lintian on every package, with nothing left but the
           overrides each package explains; the .tar.gz holds the same programs.
CFLAGS: extra compiler/linker flags for the examples (the sanitizers of a sanitized build).
"""
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tarfile

CASE, BUILD, SRC, WORK, VERSION = sys.argv[1:6]
XFLAGS = " ".join(sys.argv[6:])
FAILS = []


def check(cond, what):
    if not cond:
        FAILS.append(what)
        print("FAIL:", what, file=sys.stderr)
    return cond


def run(cmd, cwd=None, env=None, ok=True):
    p = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       text=True, timeout=600)
    if ok and p.returncode != 0:
        print("command failed (%d): %s\n%s\n%s" % (p.returncode, " ".join(cmd), p.stdout, p.stderr),
              file=sys.stderr)
        sys.exit(1)
    return p


def clean_env(**extra):
    """The user's environment without anything that would find the build tree's libraries."""
    env = {k: v for k, v in os.environ.items() if k not in ("LD_LIBRARY_PATH", "PKG_CONFIG_PATH",
                                                             "CMAKE_PREFIX_PATH")}
    env.update(extra)
    return env


def fresh(path):
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def check_programs(bindir, label):
    """selfcal and selfcald start from bindir with no LD_LIBRARY_PATH and print the version."""
    version = VERSION
    for prog in ("selfcal", "selfcald"):
        p = run([os.path.join(bindir, prog), "--version"], env=clean_env(), ok=False)
        check(p.returncode == 0 and p.stdout.strip() == "%s %s" % (prog, version),
              "%s: %s --version: rc %d, %r %r (want '%s %s')" % (label, prog, p.returncode, p.stdout,
                                                                p.stderr, prog, version))
    return version


def make_measurement(bindir, work):
    inp, gmap = os.path.join(work, "in.csv"), os.path.join(work, "G.csv")
    run([os.path.join(bindir, "selfcal"), "simulate", "grid", "--plan", "double-shift", "--n", "9",
         "--seed", "5", "--out", inp, "--truth-map", os.path.join(work, "G_true.csv")], env=clean_env())
    run([os.path.join(bindir, "selfcal"), "grid", "--method", "lsq", inp, "--map", gmap],
        env=clean_env())
    rows = {}
    with open(gmap) as f:
        header = f.readline().strip().split(",")
        for line in f:
            r = dict(zip(header, line.strip().split(",")))
            rows[(int(r["i"]), int(r["j"]))] = r
    return inp, rows


def check_example_output(exe, inp, rows, label):
    for node in ((4, 4), (2, 7)):
        p = run([exe, inp, str(node[0]), str(node[1])], env=clean_env(), ok=False)
        if not check(p.returncode == 0, "%s: rc %d (%s)" % (label, p.returncode, p.stderr.strip())):
            return
        m = re.search(r"node (\d+),(\d+) at .*: gx = (\S+) \+- (\S+) um, gy = (\S+) \+- (\S+) um", p.stdout)
        if not check(m is not None, "%s: unexpected output %r" % (label, p.stdout)):
            return
        r = rows[node]
        got = [float(m.group(k)) for k in range(3, 7)]
        want = [float(r[c]) for c in ("gx_um", "ugx_um", "gy_um", "ugy_um")]
        check(all(abs(g - w) <= 2e-6 for g, w in zip(got, want)),
              "%s: node %s = %s, the CLI's map says %s" % (label, node, got, want))
    # bad input keeps the library's contract: exit 2, one line naming file and line
    bad = os.path.join(os.path.dirname(inp), "bad.csv")
    with open(inp) as f, open(bad, "w") as g:
        lines = f.read().splitlines()
        lines[-1] = lines[-1].rsplit(",", 1)[0] + ",not-a-number"
        g.write("\n".join(lines) + "\n")
    p = run([exe, bad], env=clean_env(), ok=False)
    check(p.returncode == 2 and len(p.stderr.splitlines()) == 1 and
          re.search(r"bad\.csv:%d: " % len(lines), p.stderr),
          "%s on bad input: rc %d, stderr %r" % (label, p.returncode, p.stderr))


def sc_api_names(incdir):
    """The functions the installed headers mark SC_API; and those declared without it."""
    names, unmarked = set(), []
    for h in glob.glob(os.path.join(incdir, "selfcal", "*.h")):
        text = open(h).read()
        names.update(re.findall(r"^SC_API\b[^;(]*?\b(sc_\w+)\s*\(", text, re.M))
        unmarked += ["%s: %s" % (os.path.basename(h), n) for n in re.findall(
            r"^(?!SC_API\b|static\b|typedef\b|extern\b|return\b)(?:const\s+)?(?:unsigned\s+)?[A-Za-z_]\w*[\s*]+(sc_\w+)\s*\(",
            text, re.M)]
    return names, unmarked


def check_unit_verifies():
    """The daemon's components installed at a custom prefix (not moved): systemd-analyze verify
    accepts the unit (its man page named as a file there), and installing again keeps the
    configuration an administrator edited."""
    prefix = fresh(os.path.join(WORK, "unit-prefix"))
    for component in ("lib", "daemon"):
        run(["cmake", "--install", BUILD, "--prefix", prefix, "--component", component])
    conf = os.path.join(prefix, "etc/selfcal/selfcald.conf")
    with open(conf, "a") as f:
        f.write("# edited by the administrator\n")
    run(["cmake", "--install", BUILD, "--prefix", prefix, "--component", "daemon"])
    check(open(conf).read().endswith("# edited by the administrator\n"),
          "installing again keeps an edited etc/selfcal/selfcald.conf")
    unit = os.path.join(prefix, "lib/systemd/system/selfcald.service")
    check("Documentation=file:%s/share/man/man8/selfcald.8 " % prefix in open(unit).read(),
          "the unit at a custom prefix names its man page as a file")
    if not check(shutil.which("systemd-analyze") is not None, "systemd-analyze is installed (scripts/install-deps.sh)"):
        return
    p = run(["systemd-analyze", "verify", unit], ok=False)
    print("systemd-analyze verify %s: exit %d %s" % (unit, p.returncode, p.stderr.strip()))
    check(p.returncode == 0 and "selfcald" not in p.stderr, "systemd-analyze verify passes: %r" % p.stderr)


def case_install():
    stage = fresh(os.path.join(WORK, "stage"))
    run(["cmake", "--install", BUILD, "--prefix", stage])
    prefix = os.path.join(WORK, "moved-prefix")  # a prefix that is not where it was installed
    shutil.rmtree(prefix, ignore_errors=True)
    os.rename(stage, prefix)
    bindir = os.path.join(prefix, "bin")
    libdirs = [d for d in ("lib", "lib64") + tuple(glob.glob(os.path.join(prefix, "lib", "*-linux-gnu")))
               if os.path.exists(os.path.join(prefix, d, "libselfcal.a"))]
    if not check(len(libdirs) == 1, "libselfcal.a in one library folder (found %r)" % libdirs):
        return
    libdir = os.path.join(prefix, libdirs[0])
    for rel in ("bin/selfcal", "bin/selfcald", "include/selfcal/version.h", "include/selfcal/grid_lsq.h",
                "include/selfcal/api.h", "share/man/man1/selfcal.1", "share/man/man8/selfcald.8",
                "lib/systemd/system/selfcald.service", "share/doc/selfcal/selfcald.conf.example",
                "share/doc/selfcal/examples/grid_node.c",
                "share/doc/selfcal/examples/python/calibrate_stage.py", "share/doc/selfcal/LICENSE",
                "share/doc/selfcal/copyright"):
        check(os.path.isfile(os.path.join(prefix, rel)), "installed %s" % rel)
    # the installed README's and docs' links to documents (.md, the CAN database) and examples
    # lead to installed files, as in the source tree
    docdir = os.path.join(prefix, "share/doc/selfcal")
    mds = [os.path.join(docdir, "README.md")] + glob.glob(os.path.join(docdir, "docs", "*.md"))
    check(len(mds) > 10, "the docs are installed under share/doc/selfcal/docs: %r" % mds)
    for md in mds:
        for link in re.findall(r"\]\(([^)#:]+?)(?:#[^)]*)?\)", open(md).read()):
            if link.endswith((".md", ".dbc")) or link.startswith("examples/"):
                target = os.path.normpath(os.path.join(os.path.dirname(md), link))
                check(os.path.exists(target), "%s links %s: installed" % (os.path.relpath(md, docdir), link))
    for rel in ("libselfcal.so", "libselfcal.a", "pkgconfig/selfcal.pc", "cmake/selfcal/selfcalConfig.cmake",
                "cmake/selfcal/selfcalConfigVersion.cmake"):
        check(os.path.exists(os.path.join(libdir, rel)), "installed <libdir>/%s" % rel)
    version = check_programs(bindir, "moved prefix")

    # the shared library: versioned SONAME, exports exactly the SC_API functions
    soname = run(["readelf", "-d", os.path.join(libdir, "libselfcal.so")]).stdout
    parts = version.split(".")
    major = parts[0] if parts[0] != "0" else "0." + parts[1]  # 0.x: the ABI may change per minor
    check("Library soname: [libselfcal.so.%s]" % major in soname, "SONAME libselfcal.so.%s" % major)
    check(os.path.realpath(os.path.join(libdir, "libselfcal.so")).endswith("libselfcal.so." + version),
          "libselfcal.so -> libselfcal.so.%s" % version)
    exported = set(run(["nm", "-D", "--defined-only", os.path.join(libdir, "libselfcal.so")]).stdout.split())
    exported = {s for s in exported if s.startswith("sc_")}
    declared, unmarked = sc_api_names(os.path.join(prefix, "include"))
    check(not unmarked, "public functions declared without SC_API (not exported): %s" % unmarked)
    check(declared and not (declared - exported), "SC_API functions not exported: %s" % sorted(declared - exported))
    check(not (exported - declared), "exported but not SC_API in a header: %s" % sorted(exported - exported.intersection(declared)))

    # the man pages carry the version; the unit and the man page name real installed paths
    check(("selfcal %s" % version) in open(os.path.join(prefix, "share/man/man1/selfcal.1")).read(),
          "selfcal.1 carries the version")
    pages = ["man1/selfcal.1", "man8/selfcald.8"]
    if shutil.which("halcompile"):  # the HAL component's page, selfcal_xy(9), made by halcompile
        pages.append("man9/selfcal_xy.9")
        check(os.path.isfile(os.path.join(prefix, "share/man/man9/selfcal_xy.9")), "installed selfcal_xy.9")
    for page in pages:  # well-formed roff: groff has nothing to say
        if not os.path.isfile(os.path.join(prefix, "share/man", page)):
            continue
        p = run(["groff", "-man", "-ww", "-z", os.path.join(prefix, "share/man", page)], ok=False)
        check(p.returncode == 0 and p.stderr == "", "groff -man -ww %s: %r" % (page, p.stderr))
    man1 = open(os.path.join(prefix, "share/man/man1/selfcal.1")).read()
    usage = run([os.path.join(bindir, "selfcal"), "--help"], env=clean_env()).stdout
    for cmd in sorted(set(re.findall(r"^  selfcal ([a-z][a-z-]*(?: [a-z]+)?)", usage, re.M))):
        check(cmd.replace("-", "\\-") in man1, "selfcal.1 documents 'selfcal %s'" % cmd)
    # the paths of the prefix it was installed to (stage), not the one configured (/usr/local)
    unit = open(os.path.join(prefix, "lib/systemd/system/selfcald.service")).read()
    check(re.search(r"^ExecStart=%s/bin/selfcald --config %s/etc/selfcal/selfcald.conf --allow 127\.0\.0\.0/8,::1/128$" % (re.escape(stage), re.escape(stage)), unit,
                    re.M) and "@" not in re.sub(r"^SystemCallFilter=.*$", "", unit, flags=re.M),
          "selfcald.service names the installed paths under %s: %r" % (stage, re.findall(r"^ExecStart=.*$", unit, re.M)))
    check(os.path.isfile(os.path.join(prefix, "etc/selfcal/selfcald.conf")), "installed etc/selfcal/selfcald.conf")
    check_unit_verifies()
    man8 = open(os.path.join(prefix, "share/man/man8/selfcald.8")).read()
    check("%s/bin/selfcald" % stage in man8 and "@CMAKE" not in man8,
          "selfcald.8 names %s/bin/selfcald" % stage)

    # examples, built as an outside project against the moved prefix
    work = fresh(os.path.join(WORK, "examples"))
    inp, rows = make_measurement(bindir, work)
    src = os.path.join(work, "src")
    shutil.copytree(os.path.join(prefix, "share/doc/selfcal/examples"), src)
    cflags = "-O2 -Wall -Wextra -Werror " + XFLAGS
    # PKG_CONFIG_PATH on make's command line, as the Makefile says (make < 4.4 does not hand such
    # a variable to $(shell) by itself); `make clean` runs no pkg-config
    run(["make", "-C", src, "grid_node", "grid_node_static", "CFLAGS=" + cflags, "LDFLAGS=" + XFLAGS,
         "PKG_CONFIG_PATH=" + os.path.join(libdir, "pkgconfig")], env=clean_env())
    p = run(["make", "-C", os.path.join(prefix, "share/doc/selfcal/examples"), "-n", "clean"],
            env=clean_env(), ok=False)
    check(p.returncode == 0 and p.stderr == "", "make clean runs no pkg-config: %r" % p.stderr)
    check_example_output(os.path.join(src, "grid_node"), inp, rows, "example via pkg-config (shared)")
    check_example_output(os.path.join(src, "grid_node_static"), inp, rows, "example via pkg-config (static)")
    ldd = run(["ldd", os.path.join(src, "grid_node_static")]).stdout
    check("libselfcal" not in ldd, "grid_node_static does not need libselfcal.so")
    build = os.path.join(work, "cmake-build")
    run(["cmake", "-S", src, "-B", build, "-DCMAKE_PREFIX_PATH=" + prefix, "-DCMAKE_C_FLAGS=" + cflags,
         "-DCMAKE_EXE_LINKER_FLAGS=" + XFLAGS], env=clean_env())
    run(["cmake", "--build", build], env=clean_env())
    check_example_output(os.path.join(build, "grid_node"), inp, rows, "example via find_package (shared)")
    check_example_output(os.path.join(build, "grid_node_static"), inp, rows, "example via find_package (static)")
    # the shared library needs neither FFTW's development files nor pkg-config (a .deb-only
    # machine): pkg-config and find_package with no fftw3.pc to be found
    nofftw = fresh(os.path.join(work, "no-pc"))
    env = clean_env(PKG_CONFIG_LIBDIR=nofftw, PKG_CONFIG_PATH=os.path.join(libdir, "pkgconfig"))
    p = run(["pkg-config", "--cflags", "--libs", "selfcal"], env=env, ok=False)
    check(p.returncode == 0 and "-lselfcal" in p.stdout, "pkg-config without fftw3.pc: %r" % p.stderr)
    shared_src = fresh(os.path.join(work, "shared-only"))
    shutil.copy(os.path.join(src, "grid_node.c"), shared_src)
    with open(os.path.join(shared_src, "CMakeLists.txt"), "w") as f:
        f.write("cmake_minimum_required(VERSION 3.20)\nproject(shared_only C)\n"
                "find_package(selfcal CONFIG REQUIRED)\nadd_executable(grid_node grid_node.c)\n"
                "target_link_libraries(grid_node PRIVATE selfcal::selfcal)\n")
    build = os.path.join(work, "shared-only-build")
    run(["cmake", "-S", shared_src, "-B", build, "-DCMAKE_PREFIX_PATH=" + prefix, "-DCMAKE_C_FLAGS=" + cflags,
         "-DCMAKE_EXE_LINKER_FLAGS=" + XFLAGS], env=env)
    run(["cmake", "--build", build], env=env)
    check_example_output(os.path.join(build, "grid_node"), inp, rows, "find_package without FFTW's files")
    # the complete example of README.md ("Using the library"), as printed there
    readme = open(os.path.join(SRC, "README.md")).read()
    m = re.search(r"^## Using the library$.*?^```c[^\n]*\n(.*?)^```$", readme, re.M | re.S)
    if check(m is not None, "README.md has a C example under 'Using the library'"):
        with open(os.path.join(work, "readme.c"), "w") as f:
            f.write(m.group(1))
        pc = clean_env(PKG_CONFIG_PATH=os.path.join(libdir, "pkgconfig"))
        flags = run(["pkg-config", "--cflags", "--libs", "selfcal"], env=pc).stdout.split()
        exe = os.path.join(work, "readme")
        run(["cc", "-std=c11"] + cflags.split() + [os.path.join(work, "readme.c"), "-o", exe] + flags +
            XFLAGS.split() + ["-Wl,-rpath," + libdir])
        p = run([exe, inp], env=clean_env(), ok=False)
        c = (9 - 1) // 2
        r = rows[(c, c)]
        want = "centre node: gx = %.4f +- %.4f um, gy = %.4f +- %.4f um" % tuple(
            float(r[k]) for k in ("gx_um", "ugx_um", "gy_um", "ugy_um"))
        check(p.returncode == 0 and p.stdout.startswith(want), "README example: %r, want %r" % (p.stdout, want))
    ldd = run(["ldd", os.path.join(build, "grid_node")]).stdout
    check(os.path.join(libdir, "libselfcal.so") in ldd.replace("//", "/") or prefix in ldd,
          "the CMake example uses the installed libselfcal.so: %s" % ldd)


PLACEHOLDER_CONTACT = "selfcal@localhost"  # cmake/packaging.cmake's default Maintainer address


def deb_field(deb, field):
    return run(["dpkg-deb", "-f", deb, field]).stdout.strip()


def check_lintian(debs, contact):
    """lintian on every package: nothing but the tags each package overrides with its reason
    (cmake/deb/lintian/), and, while the Maintainer is the placeholder address, its two tags."""
    if not shutil.which("lintian"):
        check(False, "lintian is installed (scripts/install-deps.sh)")
        return
    cmd = ["lintian", "--display-info", "--show-overrides", "--tag-display-limit", "0"]
    if PLACEHOLDER_CONTACT in contact:
        print("lintian: bogus-mail-host and bogus-mail-host-in-debian-changelog suppressed: the "
              "Maintainer is the placeholder %s (-DSELFCAL_PACKAGE_CONTACT sets a real one)" % PLACEHOLDER_CONTACT)
        cmd += ["--suppress-tags", "bogus-mail-host,bogus-mail-host-in-debian-changelog"]
    cache = open(os.path.join(BUILD, "CMakeCache.txt")).read()
    if re.search(r"^SELFCAL_(SANITIZE|TSAN):BOOL=ON$", cache, re.M):
        print("lintian: hardening-no-bindnow and hardening-no-fortify-functions suppressed: this build is "
              "under sanitizers, which the hardening flags are left out of (CMakeLists.txt)")
        cmd += ["--suppress-tags", "hardening-no-bindnow,hardening-no-fortify-functions"]
    p = run(cmd + debs, ok=False)
    print("lintian output (O: = overridden, each reason in /usr/share/lintian/overrides/<package>):")
    print(p.stdout + p.stderr)
    tags = [l for l in p.stdout.splitlines() if re.match(r"^[EWIXP]: ", l)]
    check(p.returncode == 0 and not tags, "lintian: no tag that is not overridden with a reason: %r" % tags)
    overridden = [l for l in p.stdout.splitlines() if l.startswith("O: ")]
    for line in overridden:
        pkg = line.split(":")[1].strip()
        root = fresh(os.path.join(WORK, "lintian-" + pkg))
        run(["dpkg-deb", "-x", [d for d in debs if os.path.basename(d).startswith(pkg + "_")][0], root])
        text = open(os.path.join(root, "usr/share/lintian/overrides", pkg)).read()
        tag = line.split()[2]
        check(re.search(r"^#.+\n(?:#.*\n|[^#\n].*\n)*?%s: %s" % (re.escape(pkg), re.escape(tag)), text, re.M),
              "the override of %s in %s is explained by a comment" % (tag, pkg))


def case_deb():
    out = fresh(os.path.join(WORK, "packages"))
    run(["cpack", "--config", os.path.join(BUILD, "CPackConfig.cmake"), "-G", "DEB;TGZ", "-B", out])
    debs = sorted(glob.glob(os.path.join(out, "*.deb")))
    tgzs = glob.glob(os.path.join(out, "*.tar.gz"))
    parts = VERSION.split(".")
    libpkg = "libselfcal" + (parts[0] if parts[0] != "0" else "0." + parts[1])
    want = {libpkg, "libselfcal-dev", "selfcal", "selfcald"}
    if shutil.which("halcompile"):
        want.add("selfcal-linuxcnc")
    names = {deb_field(d, "Package"): d for d in debs}
    if not check(set(names) == want and len(tgzs) == 1,
                 "the packages %s and one .tar.gz (%r %r)" % (sorted(want), sorted(names), tgzs)):
        return
    for pkg, d in sorted(names.items()):
        check(os.path.basename(d) == "%s_%s_%s.deb" % (pkg, VERSION, deb_field(d, "Architecture")),
              "file name of %s: %s" % (pkg, os.path.basename(d)))
    depends = {pkg: deb_field(d, "Depends") for pkg, d in names.items()}
    print("Depends:", json.dumps(depends, indent=1))
    check(re.search(r"libfftw3-double3 \(>= [0-9.]+\)", depends[libpkg]) and "libcholmod3" in depends[libpkg] and
          re.search(r"libc6 \(>= 2\.[0-9]+\)", depends[libpkg]),
          "%s depends on FFTW, libc (versioned) and CHOLMOD: %r" % (libpkg, depends[libpkg]))
    for pkg in ("libselfcal-dev", "selfcal", "selfcald"):
        check("%s (= %s)" % (libpkg, VERSION) in depends[pkg], "%s depends on %s (= %s): %r" % (pkg, libpkg, VERSION, depends[pkg]))
    check("libmodbus" in depends["selfcald"], "selfcald depends on libmodbus: %r" % depends["selfcald"])
    check("libfftw3-dev" in depends["libselfcal-dev"], "libselfcal-dev depends on libfftw3-dev")
    if "selfcal-linuxcnc" in names:
        check("linuxcnc-uspace" in depends["selfcal-linuxcnc"] and libpkg not in depends["selfcal-linuxcnc"],
              "selfcal-linuxcnc depends on LinuxCNC, not on the library (the core is compiled in)")
    sections = {pkg: deb_field(d, "Section") for pkg, d in names.items()}
    check(sections[libpkg] == "libs" and sections["libselfcal-dev"] == "libdevel", "sections: %r" % sections)

    contents = {pkg: run(["dpkg-deb", "-c", d]).stdout for pkg, d in names.items()}
    where = {libpkg: ["libselfcal.so.%s" % VERSION, "usr/share/doc/%s/copyright" % libpkg],
             "libselfcal-dev": ["usr/include/selfcal/grid_lsq.h", "usr/lib/%s/pkgconfig/selfcal.pc",
                                "usr/lib/%s/cmake/selfcal/selfcalConfig.cmake", "usr/lib/%s/libselfcal.a",
                                "usr/lib/%s/libselfcal.so "],
             "selfcal": ["usr/bin/selfcal", "man1/selfcal.1.gz", "usr/share/doc/selfcal/README.md"],
             "selfcald": ["usr/bin/selfcald", "man8/selfcald.8.gz", "systemd/system/selfcald.service",
                          "./etc/selfcal/selfcald.conf"],
             "selfcal-linuxcnc": ["modules/selfcal_xy.so", "man9/selfcal_xy.9.gz"]}
    multiarch = run(["dpkg-architecture", "-qDEB_HOST_MULTIARCH"], ok=False).stdout.strip() or "x86_64-linux-gnu"
    for pkg in names:
        for name in where[pkg] + ["usr/share/doc/%s/copyright" % pkg, "usr/share/doc/%s/changelog.gz" % pkg]:
            name = name.replace("%s", multiarch)
            check(name in contents[pkg], "%s contains %s" % (pkg, name))
        for other in names:
            if other != pkg:
                for name in where[other][:1]:  # a whole path, at the end of dpkg-deb -c's line
                    check(not re.search(r"\b%s$" % re.escape(name.replace("%s", multiarch)), contents[pkg], re.M),
                          "%s does not carry %s's %s" % (pkg, other, name))
        check("docs/man/" not in contents[pkg], "%s has no empty docs/man folder" % pkg)
        check("/LICENSE" not in contents[pkg], "%s: the licence is in copyright, no LICENSE file" % pkg)
    check(" -> libselfcal.so.%s" % VERSION.split(".")[0] in contents[libpkg] or
          re.search(r"libselfcal\.so\.0\.[0-9]+ -> libselfcal\.so\.%s" % re.escape(VERSION), contents[libpkg]),
          "%s holds the soname link" % libpkg)

    # control files: the library's ldconfig trigger (and no maintainer scripts calling ldconfig),
    # its shlibs file; the daemon's configuration is a conffile
    ctrl = {}
    for pkg, d in names.items():
        ctrl[pkg] = fresh(os.path.join(WORK, "control-" + pkg))
        run(["dpkg-deb", "-e", d, ctrl[pkg]])
    trig = os.path.join(ctrl[libpkg], "triggers")
    check(os.path.exists(trig) and "activate-noawait ldconfig" in open(trig).read(),
          "%s activates the ldconfig trigger" % libpkg)
    for script in ("postinst", "postrm"):
        check(not os.path.exists(os.path.join(ctrl[libpkg], script)), "%s has no %s (the trigger calls ldconfig)" % (libpkg, script))
    shlibs = os.path.join(ctrl[libpkg], "shlibs")
    check(os.path.exists(shlibs) and re.search(r"^libselfcal 0\.[0-9]+ %s \(>= %s\)$" % (re.escape(libpkg), re.escape(VERSION)),
                                               open(shlibs).read(), re.M), "%s has its shlibs file" % libpkg)
    conff = os.path.join(ctrl["selfcald"], "conffiles")
    check(os.path.exists(conff) and open(conff).read().split() == ["/etc/selfcal/selfcald.conf"],
          "selfcald: /etc/selfcal/selfcald.conf is a conffile")

    # every package unpacked into one scratch root (dpkg-deb -x): the programs run from it
    root = fresh(os.path.join(WORK, "deb-root"))
    for d in debs:
        run(["dpkg-deb", "-x", d, root])
    bindir = os.path.join(root, "usr", "bin")
    check_programs(bindir, ".deb unpacked")
    # under /usr the pkg-config prefix is written out (pkg-config then drops -I/usr/include), in the
    # multiarch folder
    pcs = glob.glob(os.path.join(root, "usr/lib/**/selfcal.pc"), recursive=True)
    check(len(pcs) == 1 and "/usr/lib/%s/pkgconfig/selfcal.pc" % multiarch in pcs[0] and
          re.search(r"^prefix=/usr$", open(pcs[0]).read(), re.M),
          ".deb selfcal.pc in the multiarch folder, names prefix=/usr: %r" % pcs)
    conf = open(os.path.join(root, "etc/selfcal/selfcald.conf")).read()
    check(conf == open(os.path.join(SRC, "runtime/selfcald.conf.example")).read(),
          "/etc/selfcal/selfcald.conf is the example configuration")
    cache = open(os.path.join(BUILD, "CMakeCache.txt")).read()
    sanitized = re.search(r"^SELFCAL_(SANITIZE|TSAN):BOOL=ON$", cache, re.M) is not None
    objs = glob.glob(os.path.join(root, "usr/bin/*")) + glob.glob(os.path.join(root, "usr/lib/**/*.so*"),
                                                                  recursive=True)
    for obj in objs:
        if os.path.islink(obj) or not open(obj, "rb").read(4) == b"\x7fELF":
            continue
        secs = run(["readelf", "-S", "-W", obj]).stdout
        check(".symtab" not in secs and ".debug_info" not in secs and " .comment" not in secs,
              ".deb object stripped: %s" % obj)
        if "linuxcnc" not in obj and not sanitized:  # ours, hardened unless under sanitizers
            dyn = run(["readelf", "-d", "-W", obj]).stdout
            check("BIND_NOW" in dyn or re.search(r"FLAGS_1.*\bNOW\b", dyn),
                  ".deb object hardened (bind now): %s" % obj)
    if "selfcal-linuxcnc" in names:
        page = run(["sh", "-c", "gzip -dc '%s'" % os.path.join(root, "usr/share/man/man9/selfcal_xy.9.gz")]).stdout
        check(re.search(r"^\.B loadrt selfcal_xy table=", page, re.M), "selfcal_xy(9)'s synopsis names table=")
    # the unit starts the program the package installs, with Debian's /etc
    units = glob.glob(os.path.join(root, "usr/lib/systemd/system/selfcald.service")) + \
        glob.glob(os.path.join(root, "lib/systemd/system/selfcald.service"))
    if check(len(units) == 1, ".deb unit found (%r)" % units):
        unit = open(units[0]).read()
        check(re.search(r"^ExecStart=/usr/bin/selfcald --config /etc/selfcal/selfcald.conf --allow 127\.0\.0\.0/8,::1/128$", unit, re.M) and
              re.search(r"^ReadOnlyPaths=/etc/selfcal$", unit, re.M) and
              re.search(r"^Documentation=man:selfcald\(8\) ", unit, re.M),
              ".deb unit names /usr/bin/selfcald, /etc/selfcal and man:selfcald(8): %r" %
              re.findall(r"^(?:ExecStart|ReadOnlyPaths|Documentation)=.*$", unit, re.M))
    # the CLI from the unpacked packages does real work
    work = fresh(os.path.join(WORK, "deb-run"))
    make_measurement(bindir, work)
    p = run([os.path.join(bindir, "selfcal"), "plan", os.path.join(work, "in.csv")], env=clean_env())
    check(p.stdout.startswith("identifiable: yes"), "plan from the .deb: %r" % p.stdout[:80])
    check_lintian(debs, deb_field(debs[0], "Maintainer"))
    with tarfile.open(tgzs[0]) as t:
        names = t.getnames()
        units = [n for n in names if n.endswith("/selfcald.service")]
        unit = t.extractfile(units[0]).read().decode() if len(units) == 1 else ""
    names = [n[2:] if n.startswith("./") else n for n in names]
    check("usr/local/bin/selfcal" in names and "usr/local/bin/selfcald" in names,
          ".tar.gz is a /usr/local tree holding bin/selfcal and bin/selfcald: %r" % names[:5])
    check(re.search(r"^ExecStart=/usr/local/bin/selfcald --config /usr/local/etc/selfcal/selfcald.conf --allow 127\.0\.0\.0/8,::1/128$",
                    unit, re.M) and "_CPack_Packages" not in unit,
          ".tar.gz unit names /usr/local paths: %r" % re.findall(r"^ExecStart=.*$", unit, re.M))


{"install": case_install, "deb": case_deb}[CASE]()
if FAILS:
    print("%d check(s) failed" % len(FAILS), file=sys.stderr)
    sys.exit(1)
print("ok:", CASE)
