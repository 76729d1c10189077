"""Black-box helpers for the SPEC conformance suite (Python 3 stdlib only).

Everything here is derived from the interface contract alone (the formats and commands of docs/formats.md): parsers for the SPEC's file formats,
an independent forward model of the grid (SPEC §1) and of the profile scans (SPEC §2), small dense
linear algebra, and process helpers.  No product source is consulted.
"""
import math
import os
import random
import subprocess
import sys
import tempfile

FAILURES = []
CREATED = []


def check(cond, what):
    if not cond:
        FAILURES.append(what)
        print("FAIL: " + what, flush=True)
    return cond


def finish(name):
    if FAILURES:
        print("%s: %d failure(s)" % (name, len(FAILURES)))
        sys.exit(1)
    print("%s: ok" % name)
    import shutil
    for d in CREATED:  # keep the evidence of a failing run, clean up after a passing one
        shutil.rmtree(d, ignore_errors=True)
    sys.exit(0)


def run(args, cwd=None, timeout=60):
    p = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def tmpdir(base, name):
    os.makedirs(base, exist_ok=True)
    d = tempfile.mkdtemp(prefix="spec_" + name + "_", dir=base)
    CREATED.append(d)
    return d


# ---------------------------------------------------------------- CSV / headers
def read_csv(path):
    """Return (comment lines, header fields, rows as dicts of strings)."""
    comments, header, rows = [], None, []
    with open(path) as fh:
        for line in fh:
            line = line.rstrip("\n").rstrip("\r")
            if line.startswith("#"):
                comments.append(line)
                continue
            if not line.strip():
                continue
            fields = line.split(",")
            if header is None:
                header = fields
            else:
                if len(fields) != len(header):
                    raise ValueError("%s: row with %d fields, header has %d" % (path, len(fields), len(header)))
                rows.append(dict(zip(header, fields)))
    return comments, header, rows


def header_kv(comments):
    kv = {}
    for c in comments:
        body = c[1:].strip()
        if "=" in body and not body.startswith("view") and not body.startswith("scan"):
            k, v = body.split("=", 1)
            kv[k.strip()] = v.strip()
    return kv


# ---------------------------------------------------------------- grid geometry (SPEC §1)
def rot_vec(rot, x, y):
    r = rot % 360
    if r == 0:
        return x, y
    if r == 90:
        return -y, x
    if r == 180:
        return -x, -y
    if r == 270:
        return y, -x
    raise ValueError(rot)


class View:
    def __init__(self, rot=0, sx=0, sy=0, rows=None, cols=None):
        self.rot, self.sx, self.sy, self.rows, self.cols = rot, sx, sy, rows, cols

    def header(self, k):
        s = "# view %d: rot=%d shift=%d,%d" % (k, self.rot, self.sx, self.sy)
        if self.rows is not None:
            s += " rows=" + ",".join(str(r) for r in self.rows)
        if self.cols is not None:
            s += " cols=" + ",".join(str(c) for c in self.cols)
        return s

    def measured_marks(self, n):
        """[(i, j, node_i, node_j)] for the marks this view measures (SPEC §1 rules)."""
        c = (n - 1) // 2
        out = []
        for i in range(n):
            for j in range(n):
                if self.rows is not None or self.cols is not None:
                    ok = (self.rows is not None and i in self.rows) or (self.cols is not None and j in self.cols)
                    if not ok:
                        continue
                xr, yr = rot_vec(self.rot, j - c, i - c)
                nj, ni = c + xr + self.sx, c + yr + self.sy
                if 0 <= ni < n and 0 <= nj < n:
                    out.append((i, j, ni, nj))
        return out


YE = lambda n: [View(0), View(90), View(0, 1, 0)]
PETRO = lambda n: [View(0), View(90), View(0, 2, 0), View(0, -3, 0, rows=[(n - 1) // 2], cols=[(n - 1) // 2, (n - 1) // 2 + 1])]


def smooth_field(n, rng, amp_um):
    """Random smooth-ish per-node field (in um): a few low-order terms + white part."""
    a = [rng.gauss(0, 1) for _ in range(6)]
    g = {}
    for i in range(n):
        for j in range(n):
            u, v = j / max(1, n - 1), i / max(1, n - 1)
            g[(i, j)] = amp_um * (a[0] * math.sin(3 * u + a[1]) * math.cos(2 * v + a[2]) + a[3] * u * v + 0.3 * rng.gauss(0, 1))
    return g


def synthesize_grid(n, pitch, origin, views, seed, drop_view=None):
    """Truth + noise-free measurements per the SPEC model; returns dict."""
    rng = random.Random(seed)
    c = (n - 1) // 2
    gx, gy = smooth_field(n, rng, 0.7), smooth_field(n, rng, 0.7)
    # add first-order terms (translation, rotation, magnification, non-orthogonality) to G and A
    for (i, j) in list(gx):
        x, y = (j - c) * pitch, (i - c) * pitch
        gx[(i, j)] += 0.3 + 2e-4 * x - 1.5e-4 * y + 3e-4 * y
        gy[(i, j)] += -0.2 + 2e-4 * y + 1.5e-4 * x
    ax = {k: rng.gauss(0, 0.5) + 0.1 + 1e-4 * (k[1] - c) for k in gx}
    ay = {k: rng.gauss(0, 0.5) - 0.2 + 3e-4 * (k[1] - c) for k in gx}
    mis = [(rng.gauss(0, 0.2), rng.gauss(0, 0.2), rng.gauss(0, 50.0)) for _ in views]  # tx um, ty um, theta urad
    lines = []
    for k, v in enumerate(views):
        if k == drop_view:
            continue
        tx, ty, th = mis[k]
        for (i, j, ni, nj) in v.measured_marks(n):
            xn = origin[0] + (nj - c) * pitch
            yn = origin[1] + (ni - c) * pitch
            axr, ayr = rot_vec(v.rot, ax[(i, j)], ay[(i, j)])
            xc, yc = (nj - c) * pitch, (ni - c) * pitch  # relative to grid centre
            # um and urad*mm = nm -> /1000 to um; then /1000 to mm
            dx_um = gx[(ni, nj)] + axr + tx - th * yc / 1000.0
            dy_um = gy[(ni, nj)] + ayr + ty + th * xc / 1000.0
            lines.append((k, i, j, xn + dx_um / 1000.0, yn + dy_um / 1000.0))
    return {"gx": gx, "gy": gy, "ax": ax, "ay": ay, "lines": lines, "n": n, "pitch": pitch}


def gauge_truth(n, pitch, gx, gy, ax, ay):
    """Project the truth onto SPEC's gauge: G without translation, rotation and magnification;
    A without translation and rotation; G's magnification moves into A (it is the only
    combination the measurements see)."""
    c = (n - 1) // 2
    nodes = list(gx)
    xs = {k: (k[1] - c) * pitch for k in nodes}
    ys = {k: (k[0] - c) * pitch for k in nodes}
    m = len(nodes)
    r2 = sum(xs[k] ** 2 + ys[k] ** 2 for k in nodes)
    mgx = sum(gx.values()) / m
    mgy = sum(gy.values()) / m
    w = sum(xs[k] * gy[k] - ys[k] * gx[k] for k in nodes) / r2
    s = sum(xs[k] * gx[k] + ys[k] * gy[k] for k in nodes) / r2
    Gx = {k: gx[k] - mgx + w * ys[k] - s * xs[k] for k in nodes}
    Gy = {k: gy[k] - mgy - w * xs[k] - s * ys[k] for k in nodes}
    # A: plate-centred positions; add G's magnification, then remove translation and rotation
    Ax = {k: ax[k] + s * xs[k] for k in nodes}
    Ay = {k: ay[k] + s * ys[k] for k in nodes}
    max_ = sum(Ax.values()) / m
    may_ = sum(Ay.values()) / m
    wa = sum(xs[k] * Ay[k] - ys[k] * Ax[k] for k in nodes) / r2
    Ax = {k: Ax[k] - max_ + wa * ys[k] for k in nodes}
    Ay = {k: Ay[k] - may_ - wa * xs[k] for k in nodes}
    return Gx, Gy, Ax, Ay


def write_grid_file(path, n, pitch, origin, views, lines, origin_line=True, shuffle_seed=None,
                    view_ids=None, header_extra=()):
    hdr = ["# selfcal-grid v1", "# N = %d" % n, "# pitch_mm = %r" % float(pitch)]
    if origin_line:
        hdr.append("# origin_mm = %r,%r" % (float(origin[0]), float(origin[1])))
    for k, v in enumerate(views):
        if view_ids is not None and k not in view_ids:
            continue
        hdr.append(v.header(k))
    hdr.extend(header_extra)
    body = list(lines) if lines is not None else []
    if shuffle_seed is not None:
        random.Random(shuffle_seed).shuffle(body)
    with open(path, "w") as fh:
        fh.write("\n".join(hdr) + "\n")
        if lines is not None:
            fh.write("view,i,j,x_mm,y_mm\n")
            for (k, i, j, x, y) in body:
                fh.write("%d,%d,%d,%.15f,%.15f\n" % (k, i, j, x, y))


# ---------------------------------------------------------------- small dense linear algebra
def solve_dense(A, b):
    """Gaussian elimination with partial pivoting; A list of lists (copied)."""
    n = len(A)
    M = [list(A[r]) + [b[r]] for r in range(n)]
    for col in range(n):
        piv = max(range(col, n), key=lambda r: abs(M[r][col]))
        M[col], M[piv] = M[piv], M[col]
        p = M[col][col]
        if p == 0:
            raise ZeroDivisionError("singular")
        for r in range(col + 1, n):
            f = M[r][col] / p
            if f:
                Mr, Mc = M[r], M[col]
                for cc in range(col, n + 1):
                    Mr[cc] -= f * Mc[cc]
    x = [0.0] * n
    for r in range(n - 1, -1, -1):
        s = M[r][n] - sum(M[r][cc] * x[cc] for cc in range(r + 1, n))
        x[r] = s / M[r][r]
    return x


def invert_dense(A):
    n = len(A)
    M = [list(A[r]) + [1.0 if c == r else 0.0 for c in range(n)] for r in range(n)]
    for col in range(n):
        piv = max(range(col, n), key=lambda r: abs(M[r][col]))
        M[col], M[piv] = M[piv], M[col]
        p = M[col][col]
        if p == 0:
            raise ZeroDivisionError("singular")
        inv = 1.0 / p
        Mc = M[col]
        for cc in range(2 * n):
            Mc[cc] *= inv
        for r in range(n):
            if r != col:
                f = M[r][col]
                if f:
                    Mr = M[r]
                    for cc in range(col, 2 * n):
                        Mr[cc] -= f * Mc[cc]
    return [row[n:] for row in M]


def rank_mod_p(rows, ncols, p=2305843009213693951):
    """Exact rank (mod a large prime) of an integer matrix given as a list of {col: int} dicts."""
    pivots = {}
    rank = 0
    for row in rows:
        r = {c: v % p for c, v in row.items() if v % p}
        while r:
            c = min(r)
            if c in pivots:
                prow = pivots[c]
                f = r[c]
                for cc, vv in prow.items():
                    nv = (r.get(cc, 0) - f * vv) % p
                    if nv:
                        r[cc] = nv
                    else:
                        r.pop(cc, None)
            else:
                inv = pow(r[c], p - 2, p)
                r = {cc: vv * inv % p for cc, vv in r.items()}
                pivots[c] = r
                rank += 1
                break
    return rank


def ls_line_residual(xs, ys):
    n = len(xs)
    mx = sum(xs) / n
    my = sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    return [y - my - b * (x - mx) for x, y in zip(xs, ys)]
