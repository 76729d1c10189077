"""Writers of measuring software's exports (SPEC §10a), the fixtures of docs/import.md's recipes.

Each writer takes one view's measured mark centres and writes them the way that software lays out
its export, following its public documentation where there is one; its docstring cites the
source. The points are given as (id, x_mm, y_mm, nominal_x_mm, nominal_y_mm), x/y None for a mark
the machine did not measure. Values are written with the decimals the recipe asks for, so the test
can solve the very same rounded numbers directly (rounded() below).
"""


def rounded(v, dec, scale=1.0):
    """v (mm) as the export writes it (dec decimals in its unit, mm * scale), back in mm."""
    return float("%.*f" % (dec, v * scale)) / scale


def _f(v, dec, scale=1.0, comma=False):
    s = "%.*f" % (dec, v * scale)
    return s.replace(".", ",") if comma else s


def pcdmis_csv(path, pts, dec=6):
    """Hexagon's statistics CSV (PC-DMIS / NC Gage): 'NCG Appendix F - CSV Format',
    https://docs.hexagonmi.com/nc_server/2023.1/en/nc-gage/ncg-appendix-f---csv-format.html:
    line 1 blank, line 2 'DateTime, "<stamp>"', line 3 'Part Name, <program>', line 4 blank,
    line 5 the headings FEATURE, AXIS, NOMINAL, MEAS, +TOL, -TOL, DEV, OUTTOL, then one row per
    characteristic, every field in double quotes: X, Y, Z, D and Roundness rows of each circle.
    (The document states 4 decimals; the recipe asks for more where the software allows it.)"""
    with open(path, "w", newline="") as f:
        f.write("\r\nDateTime, \"20261128101500123\"\r\nPart Name, GRIDPLATE.PRG\r\n\r\n")
        f.write("FEATURE, AXIS, NOMINAL, MEAS, +TOL, -TOL, DEV, OUTTOL\r\n")
        for name, x, y, nx, ny in pts:
            if x is None:
                continue  # a circle not measured is not in the statistics file
            feat = "%s(Bore)" % name
            for ax, nom, meas in (("X", nx, x), ("Y", ny, y), ("Z", 0.0, 0.0),
                                  ("D", 0.3, 0.3), ("Roundness", 0.0, 0.0)):
                row = [feat, ax, _f(nom, dec), _f(meas, dec), _f(0.01, dec), _f(-0.01, dec),
                       _f(meas - nom, dec), _f(0.0, dec)]
                f.write(",".join('"%s"' % c for c in row) + "\r\n")


CALYPSO_CHR_COLUMNS = ["planid", "partnb", "id", "type", "idsymbol", "actual", "nominal",
                       "uppertol", "lowertol", "deviation", "exceed", "featureid",
                       "featuresigma", "comment", "link", "linkmode", "mmc", "useruppertol",
                       "userlowertol", "fformat", "merkmalsklasse", "natuppertol",
                       "natlowertol", "datumAid", "datumBid", "datumCid", "groupid1",
                       "groupid2", "groupid3", "groupid4", "groupid5", "groupid6", "groupid7",
                       "groupid8", "groupid9", "groupid10", "date", "time", "operator",
                       "machine", "duration", "drawing", "order", "partid", "unit"]


def calypso_chr(path, pts, dec=6):
    """Zeiss CALYPSO's characteristics table file (*_chr.txt, one row per characteristic,
    tab-separated, the header line ending in a tab). Column names as in CALYPSO's table files
    (planid, partnb, id, type, idsymbol, actual, nominal, uppertol, lowertol, deviation, exceed,
    featureid, ...), after the layout the issue describes ('45 fields, the header line has 46');
    no public specification of the file could be retrieved here, so the characteristic type
    names 'X Value' and 'Y Value' are given to the import with --axis-names, as a user reads
    them off their own file."""
    cols = CALYPSO_CHR_COLUMNS
    with open(path, "w", newline="") as f:
        f.write("\t".join(cols) + "\t\r\n")
        for name, x, y, nx, ny in pts:
            for kind, meas, nom in (("X Value", x, nx), ("Y Value", y, ny), ("Diameter", 0.3, 0.3)):
                row = dict.fromkeys(cols, "")
                row.update(planid="GRIDPLATE", partnb="1", id="%s %s" % (kind, name),
                           type=kind, idsymbol="", actual=_f(meas, dec) if meas is not None else "",
                           nominal=_f(nom, dec), uppertol="0.01", lowertol="-0.01",
                           deviation=_f(meas - nom, dec) if meas is not None else "",
                           exceed="0", featureid=name, unit="mm", date="28.11.2026",
                           time="10:15:00", operator="Master")
                f.write("\t".join(row[c] for c in cols) + "\r\n")


CALYPSO_FET_COLUMNS = ["planid", "partnb", "id", "type", "x", "y", "z", "nx", "ny", "nz", "d",
                       "form", "points", "date", "time"]


def calypso_fet(path, pts, dec=6):
    """Zeiss CALYPSO's features table file (*_fet.txt): one row per feature with its actual
    position, tab-separated, the header line ending in a tab. It lists the alignment features
    (the plane of the plate's surface, the line along its first row, the origin point on the
    centre mark) before the circles; their centres land on marks, so the import reads only the
    circles (--where type=Circle). Layout as described for CALYPSO's table files (no public
    specification retrievable here; the column names are an assumption a user checks against
    their file)."""
    cols = CALYPSO_FET_COLUMNS
    with open(path, "w", newline="") as f:
        f.write("\t".join(cols) + "\t\r\n")

        def row(i, typ, x, y):
            vals = ["GRIDPLATE", "1", i, typ, x, y, _f(0.0, dec), "0", "0", "1",
                    "0.3" if typ == "Circle" else "", "0.0002", "12", "28.11.2026", "10:15:00"]
            f.write("\t".join(vals) + "\r\n")
        row("Plane_Surface", "Plane", _f(0.0, dec), _f(0.0, dec))
        row("Line_Row1", "Line", _f(0.0, dec), _f(pts[0][4], dec))
        row("Point_Origin", "Point", _f(0.0, dec), _f(0.0, dec))
        for name, x, y, nx, ny in pts:
            if x is not None:
                row(name, "Circle", _f(x, dec), _f(y, dec))


def geopak(path, pts, dec=6):
    """Mitutoyo GEOPAK (MCOSMOS) tolerance output through a GEOPAK ASCII Format file: F.
    Lehrbass, 'Text file output using GEOPAK ASCII Format', v1.20, 2019
    (https://studylib.net/doc/26976752/text-file-output-using-geopak-ascii-format): the
    tolerance lines Tol_PosX / Tol_PosY are
    «ElemNo»;«TolName»;«FeatName»;«Nominal»;«UpperTol»;«LowerTol»;«Actual»;«Deviation»;
    «OutOfSpec»;«TolBar», ';'-separated, the decimal separator set in the GAF file (',' here),
    and no head line unless the GAF file defines one. The tolerance bar is text (no digits)."""
    with open(path, "w", newline="", encoding="cp1252") as f:
        for k, (name, x, y, nx, ny) in enumerate(pts):
            for tol, meas, nom in (("PosX", x, nx), ("PosY", y, ny)):
                if meas is None:
                    continue
                dev = meas - nom
                bar = "----|--*-" if dev >= 0 else "-*--|----"
                f.write(";".join([str(k + 1), tol, name, _f(nom, dec, comma=True), "0,010",
                                  "-0,010", _f(meas, dec, comma=True), _f(dev, dec, comma=True),
                                  "", bar]) + "\r\n")


def vision_sjis(path, pts, dec=4):
    """A vision measuring system's result CSV as Japanese systems write it: Shift-JIS text,
    a header naming the columns in Japanese (番号, 名前, X座標, Y座標, 判定), values in µm,
    '-----' where a mark was not detected. No public specification was found; the layout is
    that of a typical image measuring system's CSV result file (an assumption)."""
    with open(path, "w", newline="", encoding="cp932") as f:
        f.write("番号,名前,X座標,Y座標,判定\r\n")
        for k, (name, x, y, nx, ny) in enumerate(pts):
            if x is None:
                f.write("%d,%s,-----,-----,NG\r\n" % (k + 1, name))
            else:
                f.write("%d,%s,%s,%s,OK\r\n" % (k + 1, name, _f(x, dec, 1000), _f(y, dec, 1000)))


def excel_de(path, pts, dec=4):
    """A German Excel sheet saved as 'CSV (Trennzeichen-getrennt)': Windows-1252 text, ';' and
    decimal commas, nominal and actual columns (Soll, Ist) in µm, 'n. g.' (nicht gemessen) for a
    mark not measured, and Excel's summary rows under the table, labelled with German function
    names (MITTELWERT, STABW, MIN, MAX; German names of Excel's functions:
    https://excelhero.de/funktionen/excel-stabw-funktion/)."""
    rows = ["Meßpunkt;X-Soll [µm];Y-Soll [µm];X-Ist [µm];Y-Ist [µm]"]
    xs, ys = [], []
    for name, x, y, nx, ny in pts:
        if x is None:
            rows.append("%s;%s;%s;n. g.;n. g." % (name, _f(nx, 1, 1000, True),
                                                  _f(ny, 1, 1000, True)))
            continue
        xs.append(x)
        ys.append(y)
        rows.append(";".join([name, _f(nx, 1, 1000, True), _f(ny, 1, 1000, True),
                              _f(x, dec, 1000, True), _f(y, dec, 1000, True)]))
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sx = (sum((v - mx) ** 2 for v in xs) / (len(xs) - 1)) ** 0.5
    sy = (sum((v - my) ** 2 for v in ys) / (len(ys) - 1)) ** 0.5
    rows.append(";;;;")
    for label, a, b in (("Mittelwert", mx, my), ("Stabw.", sx, sy), ("Min", min(xs), min(ys)),
                        ("Max", max(xs), max(ys))):
        rows.append("%s;;;%s;%s" % (label, _f(a, dec, 1000, True), _f(b, dec, 1000, True)))
    with open(path, "w", newline="", encoding="cp1252") as f:
        f.write("\r\n".join(rows) + "\r\n")


def excel_transposed(path, pts, dec=6):
    """A spreadsheet with one column per point (items in columns): the first row names the
    points, the rows below are labelled X and Y in their first field, a 'Mittelwert' column
    at the end (as excel_de, Windows-1252, ';' and decimal commas, mm)."""
    named = [p for p in pts if p[1] is not None]
    mx = sum(p[1] for p in named) / len(named)
    my = sum(p[2] for p in named) / len(named)
    lines = [";".join(["Merkmal"] + [p[0] for p in named] + ["Mittelwert"]),
             ";".join(["X"] + [_f(p[1], dec, comma=True) for p in named] + [_f(mx, dec, comma=True)]),
             ";".join(["Y"] + [_f(p[2], dec, comma=True) for p in named] + [_f(my, dec, comma=True)])]
    with open(path, "w", newline="", encoding="cp1252") as f:
        f.write("\r\n".join(lines) + "\r\n")


# recipe name in docs/import.md -> (writer, decimals, unit scale of the written values)
WRITERS = {
    "pcdmis": (pcdmis_csv, 6, 1.0),
    "calypso-chr": (calypso_chr, 6, 1.0),
    "calypso-fet": (calypso_fet, 6, 1.0),
    "geopak": (geopak, 6, 1.0),
    "vision": (vision_sjis, 4, 1000.0),
    "excel": (excel_de, 4, 1000.0),
    "excel-columns": (excel_transposed, 6, 1.0),
}
