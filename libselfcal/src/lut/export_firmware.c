/* export_firmware.c — the first-order part of a stage error map (non-orthogonality O and scale R,
 * Petro eqs. 4-5) as the XY skew and scale settings of 3D-printer / small-CNC firmware, each in
 * that firmware's own parameters and following its own transform (docs/exporters.md cites them):
 *   klipper  klippy/extras/skew_correction.py: moves go to x - y * xy_factor, where xy_factor =
 *            calc_skew_factor(AC, BD, AD) of the lengths given to SET_SKEW XY=AC,BD,AD;
 *   marlin   M852 I<factor>, planner skew(): x - y * skew_factor.xy, |factor| <= 1;
 *   reprap   M556 S<length> X<deviation>, Move::AxisTransform: x + tanXY * y, tanXY = X / S.
 * Scale goes to the axes' steps/mm (M92) or rotation_distance. The residual is evaluated like
 * the table formats' (nodes and 4 x 4 sub-points per cell): the map where the firmware moves the
 * axes, G(t + c(t)), minus the firmware's correction c(t), computed from the values as written,
 * after removing the translation, rotation and magnification that a self-calibrated map leaves
 * undefined (its gauge).
 * No library does these conversions; they are a few lines each. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export_internal.h"

/* Least-squares first order of the map over its nodes, about the grid centre: Gx = b x + c y,
 * Gy = e x + f y (+ constants); dimensionless (um per um). The full regular grid makes the
 * four slopes independent sums. */
static void first_order(const sc_lut *lut, double *b, double *c, double *e, double *f)
{
    const double cx = 0.5 * (lut->nx - 1), cy = 0.5 * (lut->ny - 1);
    double sxgx = 0, sygx = 0, sxgy = 0, sygy = 0, sxx = 0, syy = 0;
    for (int i = 0; i < lut->ny; ++i)
        for (int j = 0; j < lut->nx; ++j) {
            const double x = (j - cx) * lut->px_mm, y = (i - cy) * lut->py_mm;
            const int k = i * lut->nx + j;
            sxgx += x * lut->gx_um[k];
            sygx += y * lut->gx_um[k];
            sxgy += x * lut->gy_um[k];
            sygy += y * lut->gy_um[k];
            sxx += x * x;
            syy += y * y;
        }
    /* um per mm -> um per um */
    *b = sxgx / sxx * 1e-3;
    *c = sygx / syy * 1e-3;
    *e = sxgy / sxx * 1e-3;
    *f = sygy / syy * 1e-3;
}

/* The firmware's correction, as a map: where the firmware sends the motors for target (x, y),
 * minus the target, in um. skew_x_per_y: the x shift per unit y the firmware applies (Klipper
 * and Marlin -factor, RepRapFirmware +tanXY); k: the scale factors of x and y. */
typedef struct fw_model {
    double skew_x_per_y;
    double k[2];
} fw_model;

static void fw_correction_um(const fw_model *m, double x, double y, double c_um[2])
{
    const double xs = x + m->skew_x_per_y * y; /* the firmware's skew transform */
    c_um[0] = (m->k[0] * xs - x) * 1e3;          /* then the axis scale */
    c_um[1] = (m->k[1] * y - y) * 1e3;
}

/* Residual of the map at the moved position against the firmware's correction, over nodes and
 * 4 x 4 sub-points per cell, with the gauge freedoms (translation, rotation, magnification)
 * fitted and removed. */
static void fw_residual(const sc_lut *lut, const fw_model *m, sc_export_report *rep)
{
    const int sub = 4, na = sub * (lut->ny - 1) + 1, nb = sub * (lut->nx - 1) + 1;
    const double xc = lut->x0_mm + 0.5 * (lut->nx - 1) * lut->px_mm;
    const double yc = lut->y0_mm + 0.5 * (lut->ny - 1) * lut->py_mm;
    /* Two passes: the gauge fit (symmetric sampling about the centre: the four parameters are
     * independent sums), then the statistics. */
    double srx = 0, sry = 0, srot = 0, smag = 0, sr2 = 0;
    for (int pass = 0; pass < 2; ++pass) {
        const double n = (double)na * nb;
        const double tx = srx / n, ty = sry / n, th = sr2 > 0 ? srot / sr2 : 0,
                     mg = sr2 > 0 ? smag / sr2 : 0;
        double ss = 0, mx = -1;
        for (int a = 0; a < na; ++a)
            for (int bb = 0; bb < nb; ++bb) {
                const double x = lut->x0_mm + lut->px_mm * bb / sub;
                const double y = lut->y0_mm + lut->py_mm * a / sub;
                double gx, gy, c[2];
                /* The firmware sends the motors to t + c(t): the stage then stands G(t + c)
                 * short of that, so the error left is c(t) - G(t + c(t)) (the map where the
                 * firmware moves, clamped beyond it as selfcald does), not c(t) - G(t). */
                fw_correction_um(m, x, y, c);
                sc_lut_grid_eval(lut, x + 1e-3 * c[0], y + 1e-3 * c[1], &gx, &gy);
                const double rx = gx - c[0], ry = gy - c[1], u = x - xc, v = y - yc;
                if (pass == 0) {
                    srx += rx;
                    sry += ry;
                    srot += u * ry - v * rx;
                    smag += u * rx + v * ry;
                    sr2 += u * u + v * v;
                    continue;
                }
                const double dx = rx - (tx - th * v + mg * u), dy = ry - (ty + th * u + mg * v);
                const double r[2] = {dx, dy};
                for (int q = 0; q < 2; ++q) {
                    ss += r[q] * r[q];
                    if (fabs(r[q]) > mx) {
                        mx = fabs(r[q]);
                        rep->max_at_mm[0] = x;
                        rep->max_at_mm[1] = y;
                    }
                }
            }
        if (pass == 1) {
            rep->samples = 2L * na * nb;
            rep->rms_um = sqrt(ss / (double)rep->samples);
            rep->max_um = mx;
        }
    }
}

/* Formatting into the caller's fixed buffer. */
typedef struct outbuf {
    char *s;
    size_t cap, len;
    int overflow;
} outbuf;

static void out(outbuf *b, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static void out(outbuf *b, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(b->s + b->len, b->cap - b->len, fmt, ap);
    va_end(ap);
    if (n < 0 || (size_t)n >= b->cap - b->len)
        b->overflow = 1;
    else
        b->len += (size_t)n;
}

/* A value printed with %.*f and read back, as the firmware will read it. */
static double as_written(double v, int decimals)
{
    char t[64];
    snprintf(t, sizeof t, "%.*f", decimals, v);
    return strtod(t, NULL);
}

/* Klipper's calc_skew_factor(ac, bd, ad) (skew_correction.py). */
static double klipper_skew_factor(double ac, double bd, double ad)
{
    const double side = sqrt(2 * ac * ac + 2 * bd * bd - 4 * ad * ad) / 2.;
    return tan(M_PI / 2 - acos((ac * ac - side * side - ad * ad) / (2 * side * ad)));
}

#define KLIPPER_AD_MM 100.0  /* the virtual calibration square's side */
#define REPRAP_S_MM 1000.0   /* M556 S: the length over which the deviation X is given */
#define FW_DECIMALS 9

/* The scale lines: absolute values when the present ones are known, else the factors. */
static void scale_lines(outbuf *b, const char *cmt, const char *what, const double present[2],
                        const double k[2], const char *cmd)
{
    if (present[0] > 0 && present[1] > 0) {
        out(b, "%s scale R: %s X %.9g -> %.9f, Y %.9g -> %.9f\n", cmt, what, present[0],
            present[0] * k[0], present[1], present[1] * k[1]);
        if (cmd)
            out(b, "%s X%.9f Y%.9f\n", cmd, present[0] * k[0], present[1] * k[1]);
        else
            out(b, "%s [stepper_x] rotation_distance: %.9f\n%s [stepper_y] rotation_distance: "
                   "%.9f\n",
                cmt, present[0] * k[0], cmt, present[1] * k[1]);
    } else {
        out(b, "%s scale R: multiply the %s of X by %.9f and of Y by %.9f\n", cmt, what, k[0],
            k[1]);
    }
}

/* The options a firmware export takes: no --negate, finite non-negative steps and distances. */
static sc_status fw_check_options(const sc_export_options *o, sc_error *err)
{
    if (o->negate)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "firmware formats follow the firmware's own sign: negate does not "
                            "apply");
    for (int a = 0; a < 2; ++a)
        if (!(o->steps_per_mm[a] >= 0) || !(o->rotation_distance_mm[a] >= 0) ||
            !isfinite(o->steps_per_mm[a]) || !isfinite(o->rotation_distance_mm[a]))
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "steps/mm and rotation distance must be finite and > 0");
    return SC_OK;
}

/* Scale factors as written (9 decimals), applied to steps/mm (k) or rotation_distance (1/k). */
static void fw_scales(int klipper, double R, fw_model *m, sc_export_report *rep)
{
    if (klipper) {
        const double rx = as_written(1.0 - R, FW_DECIMALS), ry = as_written(1.0 + R, FW_DECIMALS);
        rep->scale[0] = rx;
        rep->scale[1] = ry;
        m->k[0] = 1.0 / rx;
        m->k[1] = 1.0 / ry;
    } else {
        rep->scale[0] = as_written(1.0 / (1.0 - R), FW_DECIMALS);
        rep->scale[1] = as_written(1.0 / (1.0 + R), FW_DECIMALS);
        m->k[0] = rep->scale[0];
        m->k[1] = rep->scale[1];
    }
}

/* Klipper: SET_SKEW takes the lengths of a printed square; give those of a virtual one whose
 * calc_skew_factor is the factor we need: -2 O (Klipper moves to x - y * factor). */
static void fw_write_klipper(outbuf *ob, const sc_export_options *o, double want, fw_model *m,
                             sc_export_report *rep)
{
    const char *cmt = ";";
    const double fac = -want, theta = M_PI / 2 - atan(fac), L = KLIPPER_AD_MM;
    const double ac = as_written(L * sqrt(2 + 2 * cos(theta)), FW_DECIMALS);
    const double bd = as_written(L * sqrt(2 - 2 * cos(theta)), FW_DECIMALS);
    rep->skew = klipper_skew_factor(ac, bd, L);
    m->skew_x_per_y = -rep->skew;
    out(ob, "%s Klipper skew_correction moves to x - y * xy_factor, xy_factor = "
            "calc_skew_factor(AC, BD, AD);\n",
        cmt);
    out(ob, "%s these are the lengths of a virtual %.0f mm square with xy_factor = %.9g\n", cmt,
        L, rep->skew);
    out(ob, "%s printer.cfg needs a [skew_correction] section; then run (or put in the start "
            "macro):\n",
        cmt);
    out(ob, "SET_SKEW XY=%.*f,%.*f,%.*f\n", FW_DECIMALS, ac, FW_DECIMALS, bd, FW_DECIMALS, L);
    /* skew_correction starts every boot at 0: a saved profile is only applied once loaded */
    out(ob, "%s Klipper starts with no skew at every restart: to keep it, SKEW_PROFILE "
            "SAVE=selfcal and SAVE_CONFIG once,\n", cmt);
    out(ob, "%s then SKEW_PROFILE LOAD=selfcal in the start macro after homing (and SET_SKEW "
            "CLEAR=1 in the end macro)\n", cmt);
    scale_lines(ob, cmt, "rotation_distance", o->rotation_distance_mm, rep->scale, NULL);
}

static sc_status fw_write_marlin(outbuf *ob, const sc_export_options *o, double want,
                                 fw_model *m, sc_export_report *rep, sc_error *err)
{
    const char *cmt = ";";
    const double I = as_written(-want, FW_DECIMALS);
    if (!(fabs(I) <= SC_EXPORT_MARLIN_MAX_SKEW))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "marlin: skew factor %.6g is beyond M852's limit |I| <= 1", I);
    rep->skew = I;
    m->skew_x_per_y = -I;
    out(ob, "%s Marlin (SKEW_CORRECTION, SKEW_CORRECTION_GCODE) moves to x - y * I\n", cmt);
    out(ob, "G21 %s M852 reads its value in the current length units: millimetres\n", cmt);
    out(ob, "M852 I%.*f\n", FW_DECIMALS, I);
    scale_lines(ob, cmt, "steps/mm (M92)", o->steps_per_mm, rep->scale, "M92");
    out(ob, "%s M500 stores these in EEPROM\n", cmt);
    return SC_OK;
}

static void fw_write_reprap(outbuf *ob, const sc_export_options *o, double want, fw_model *m,
                            sc_export_report *rep)
{
    const char *cmt = ";";
    const double X = as_written(want * REPRAP_S_MM, FW_DECIMALS - 3);
    rep->skew = X / REPRAP_S_MM;
    m->skew_x_per_y = rep->skew;
    out(ob, "%s RepRapFirmware moves to x + y * tanXY, tanXY = X / S\n", cmt);
    out(ob, "M556 S%.0f X%.*f\n", REPRAP_S_MM, FW_DECIMALS - 3, X);
    scale_lines(ob, cmt, "steps/mm (M92)", o->steps_per_mm, rep->scale, "M92");
}

/* Klipper, Marlin or RepRapFirmware text for lut's first order into buf (cap bytes, *len
 * written), report filled. SC_E_INPUT for maps beyond the firmware's limits. */
static sc_status firmware_text(const sc_lut *lut, const sc_export_options *o, char *buf,
                               size_t cap, size_t *len, sc_export_report *rep, sc_error *err)
{
    sc_status st = fw_check_options(o, err);
    if (st != SC_OK)
        return st;
    double b, c, e, f;
    first_order(lut, &b, &c, &e, &f);
    const double O = 0.5 * (c + e), R = 0.5 * (b - f);
    rep->O = O;
    rep->R = R;
    /* Machine model (G = indicated - true): true = (x - R x - O y, y + R y - O x). Up to a
     * rotation by -O it is a simple shear true_x = x - 2 O y and axis scales 1 - R, 1 + R; so
     * the motors must go to (x + 2 O y) / (1 - R) and y / (1 + R). */
    if (!(fabs(2 * O) < 1) || !(fabs(R) < 0.5))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the map's first order (O = %.3g, R = %.3g) is not a machine's "
                            "(|2 O| < 1 and |R| < 0.5 expected)",
                            O, R);
    fw_model m = {0};
    const int klipper = o->format == SC_EXPORT_KLIPPER;
    fw_scales(klipper, R, &m, rep);
    const double want = 2 * O; /* x shift per unit y the motors need */
    outbuf ob = {buf, cap, 0, 0};
    const char *cmt = ";";
    out(&ob, "%s written by selfcal export --format %s from a stage error map\n", cmt,
        klipper ? "klipper" : o->format == SC_EXPORT_MARLIN ? "marlin" : "reprap");
    out(&ob, "%s map first order (Petro eqs. 4-5, G = indicated - true): O = %.9g, R = %.9g\n",
        cmt, O, R);
    out(&ob, "%s XY angle error 2*O = %.6g rad (%.4f um per 100 mm)\n", cmt, 2 * O,
        2 * O * 100e3);
    if (klipper)
        fw_write_klipper(&ob, o, want, &m, rep);
    else if (o->format == SC_EXPORT_MARLIN)
        st = fw_write_marlin(&ob, o, want, &m, rep, err);
    else
        fw_write_reprap(&ob, o, want, &m, rep);
    if (st != SC_OK)
        return st;
    if (ob.overflow)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "firmware export: text buffer too small");
    fw_residual(lut, &m, rep);
    out(&ob, "%s residual (map where the firmware moves - firmware correction, up to "
             "translation, rotation, magnification): rms %.4f um, max %.4f um\n",
        cmt, rep->rms_um, rep->max_um);
    if (ob.overflow)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "firmware export: text buffer too small");
    rep->tables = 1;
    rep->unit_um = 1e-3;
    *len = ob.len;
    return SC_OK;
}

/* The back-ends: a few lines of text, formatted into one fixed buffer. */
static sc_status firmware_write(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                sc_export_report *rep, sc_error *err)
{
    t->cap = 8192;
    t->s = malloc(t->cap);
    return t->s ? firmware_text(lut, o, t->s, t->cap, &t->len, rep, err)
                : sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
}

const sc_export_backend sc_export_backend_klipper = {SC_EXPORT_KLIPPER, "klipper", firmware_write};
const sc_export_backend sc_export_backend_marlin = {SC_EXPORT_MARLIN, "marlin", firmware_write};
const sc_export_backend sc_export_backend_reprap = {SC_EXPORT_REPRAP, "reprap", firmware_write};
