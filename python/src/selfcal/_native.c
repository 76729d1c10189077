/* _native.c — the C extension behind `import selfcal`: thin calls into libselfcal (the shared
 * library built from the same sources as the command line), numpy arrays in and out.
 *
 * Written with the CPython and NumPy C APIs directly: the surface is a handful of calls and the
 * library is C, so a binding generator (nanobind is C++, cffi needs the structs mirrored) would
 * add more than it saves. Everything here converts arguments, calls the library and converts the
 * results; no numerical work is done in this file except the per-point loop of Table.apply, which
 * calls the correction core with the GIL released. The Python layer (__init__.py) does argument
 * checking, broadcasting and the result objects.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include <errno.h>
#include <limits.h>
#include <stdarg.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "selfcal/correct.h"
#include "selfcal/error.h"
#include "selfcal/grid.h"
#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"
#include "selfcal/lut.h"
#include "selfcal/profile.h"
#include "selfcal/profile_calibrate.h"
#include "selfcal/profile_sim.h"
#include "selfcal/verify.h"
#include "selfcal/version.h"

/* The exceptions of selfcal._errors (imported at module init): sc_py_error is InputError (a
 * selfcal.Error and a ValueError), the message of bad content or a bad argument value. */
static PyObject *sc_py_error, *exc_unsolvable, *exc_file, *exc_missing, *exc_permission,
    *exc_directory, *exc_nomem, *exc_internal;


/* selfcal.Error with a printf message: PyErr_Format knows no %g, which numbers need. */
static void error_printf(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static void error_printf(const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    PyErr_SetString(sc_py_error, msg);
}

/* The OSError subclass of selfcal._errors for a system refusal errnum (not 0). */
static PyObject *file_error_type(int errnum)
{
    switch (errnum) {
    case ENOENT: case ENOTDIR:
        return exc_missing; /* FileNotFoundError */
    case EACCES: case EPERM: case EROFS:
        return exc_permission; /* PermissionError */
    case EISDIR:
        return exc_directory; /* IsADirectoryError */
    default:
        return exc_file; /* OSError */
    }
}

/* Raise the command line's one-line message for the same error ("selfcal: FILE:LINE: reason")
 * as the standard library's kind of exception, each also a selfcal.Error: a refusal by the system
 * (the library's sys_errno) an OSError subclass with errno, strerror and filename; out of memory
 * a MemoryError; an unsolvable problem, bad input and the rest ValueError (InputError) or
 * RuntimeError (InternalError). */
static PyObject *raise_sc(const sc_error *err)
{
    char buf[1024] = "selfcal: ";
    sc_error_format(err, buf + 9, sizeof buf - 9);
    if (err->sys_errno) {
        PyObject *name = err->file[0] ? PyUnicode_DecodeFSDefault(err->file) : Py_NewRef(Py_None);
        PyObject *e = name ? PyObject_CallFunction(file_error_type(err->sys_errno), "isO",
                                                   err->sys_errno, strerror(err->sys_errno), name)
                           : NULL;
        Py_XDECREF(name);
        PyObject *msg = e ? PyUnicode_DecodeUTF8(buf, (Py_ssize_t)strlen(buf), "replace") : NULL;
        if (msg && PyObject_SetAttrString(e, "message", msg) == 0)
            PyErr_SetObject((PyObject *)Py_TYPE(e), e);
        Py_XDECREF(msg);
        Py_XDECREF(e);
        return NULL;
    }
    PyObject *type = err->code == SC_E_NOMEM         ? exc_nomem
                     : err->code == SC_E_IO          ? exc_file
                     : err->code == SC_E_UNSOLVABLE  ? exc_unsolvable
                     : err->code == SC_E_INTERNAL    ? exc_internal
                                                     : sc_py_error;
    PyErr_SetString(type, buf);
    return NULL;
}

/* A new 1-D float64 array of n elements. */
static PyArrayObject *new_vec(npy_intp n, int typenum)
{
    return (PyArrayObject *)PyArray_SimpleNew(1, &n, typenum);
}

/* A copy of a C array as a new 1-D float64 numpy array. */
static PyObject *vec_from(const double *v, npy_intp n)
{
    PyArrayObject *a = new_vec(n, NPY_DOUBLE);
    if (a && n)
        memcpy(PyArray_DATA(a), v, (size_t)n * sizeof(double));
    return (PyObject *)a;
}

/* A path argument (str, bytes or os.PathLike) as a new bytes object, or NULL (no exception) if
 * obj is not one. */
static PyObject *as_path(PyObject *obj)
{
    if (!PyUnicode_Check(obj) && !PyBytes_Check(obj) && !PyObject_HasAttrString(obj, "__fspath__"))
        return NULL;
    PyObject *b = NULL;
    if (!PyUnicode_FSConverter(obj, &b))
        return NULL;
    return b;
}

/* Copy the float64 array `obj` of exactly n elements into dst; -1 with an exception otherwise. */
static int copy_vec(PyObject *obj, double *dst, npy_intp n, const char *what)
{
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(obj, NPY_DOUBLE, 1, 1, NPY_ARRAY_IN_ARRAY);
    if (!a)
        return -1;
    if (PyArray_DIM(a, 0) != n) {
        PyErr_Format(sc_py_error, "%s has %zd values, expected %zd", what,
                     (Py_ssize_t)PyArray_DIM(a, 0), (Py_ssize_t)n);
        Py_DECREF(a);
        return -1;
    }
    memcpy(dst, PyArray_DATA(a), (size_t)n * sizeof(double));
    Py_DECREF(a);
    return 0;
}

/* An optional float (None -> NaN). */
/* A Python int into a C int: selfcal.Error (not a silent truncation) beyond its range. */
static int as_int(PyObject *o, const char *what, int *out)
{
    long v = PyLong_AsLong(o);
    if (v == -1 && PyErr_Occurred()) {
        if (!PyErr_ExceptionMatches(PyExc_OverflowError) && !PyErr_ExceptionMatches(PyExc_TypeError))
            return -1;
        PyErr_Clear();
        PyErr_Format(sc_py_error, "%s must be a whole number within +-%d", what, INT_MAX);
        return -1;
    }
    if (v < INT_MIN || v > INT_MAX) {
        PyErr_Format(sc_py_error, "%s = %ld is beyond +-%d", what, v, INT_MAX);
        return -1;
    }
    *out = (int)v;
    return 0;
}

/* An optional noise: None (not given) or a finite number >= 0; selfcal.Error otherwise (NaN
 * too: "not given" is None). */
static int opt_noise(PyObject *o, const char *what, double *v)
{
    if (o == Py_None) {
        *v = NAN;
        return 0;
    }
    *v = PyFloat_AsDouble(o);
    if (*v == -1.0 && PyErr_Occurred())
        return -1;
    if (!(*v >= 0) || !isfinite(*v)) {
        error_printf("%s must be a finite number >= 0 (None: not given), got %g", what, *v);
        return -1;
    }
    return 0;
}

static int opt_double(PyObject *o, double *v)
{
    if (o == Py_None) {
        *v = NAN;
        return 0;
    }
    *v = PyFloat_AsDouble(o);
    return (*v == -1.0 && PyErr_Occurred()) ? -1 : 0;
}

/* ---- straightness profiles ---- */

/* The measurement as a dict: n, s_mm, d1, d2, m1_um, m2_um, m3_urad (tuples of the two scans'
 * arrays), sigma_disp_um and sigma_angle_urad (None when the data do not state them). */
static PyObject *profile_to_dict(const sc_profile_data *d)
{
    PyObject *sc[3][2] = {{NULL}};
    for (int k = 0; k < 2; ++k) {
        npy_intp m = d->n - d->d[k];
        sc[0][k] = vec_from(d->m1_um[k], m);
        sc[1][k] = vec_from(d->m2_um[k], m);
        sc[2][k] = vec_from(d->m3_urad[k], m);
    }
    for (int a = 0; a < 3; ++a)
        for (int k = 0; k < 2; ++k)
            if (!sc[a][k]) {
                for (int b = 0; b < 3; ++b)
                    for (int q = 0; q < 2; ++q)
                        Py_XDECREF(sc[b][q]);
                return NULL;
            }
    PyObject *sd = d->has_sigma_disp ? PyFloat_FromDouble(d->sigma_disp_um) : Py_NewRef(Py_None);
    PyObject *sa = d->has_sigma_angle ? PyFloat_FromDouble(d->sigma_angle_urad) : Py_NewRef(Py_None);
    return Py_BuildValue("{s:i,s:d,s:i,s:i,s:(NN),s:(NN),s:(NN),s:N,s:N}", "n", d->n, "s_mm",
                         d->s_mm, "d1", d->d[0], "d2", d->d[1], "m1_um", sc[0][0], sc[0][1],
                         "m2_um", sc[1][0], sc[1][1], "m3_urad", sc[2][0], sc[2][1],
                         "sigma_disp_um", sd, "sigma_angle_urad", sa);
}

/* Fill d (allocated here) from a dict as profile_to_dict makes; -1 with an exception. */
static int profile_from_dict(PyObject *dict, sc_profile_data *d)
{
    memset(d, 0, sizeof *d);
    if (!PyDict_Check(dict)) {
        PyErr_SetString(sc_py_error, "a profile measurement file path or a "
                                     "selfcal.ProfileMeasurement is needed");
        return -1;
    }
    int n, d1, d2;
    double s_mm, sd, sa;
    PyObject *m[3], *osd, *osa;
    static const char *keys[3] = {"m1_um", "m2_um", "m3_urad"};
    PyObject *t = Py_BuildValue("(O)", dict);
    if (!t)
        return -1;
    int ok = PyArg_ParseTuple(t, "O!", &PyDict_Type, &dict);
    Py_DECREF(t);
    if (!ok)
        return -1;
    PyObject *on = PyDict_GetItemString(dict, "n"), *os = PyDict_GetItemString(dict, "s_mm"),
             *od1 = PyDict_GetItemString(dict, "d1"), *od2 = PyDict_GetItemString(dict, "d2");
    osd = PyDict_GetItemString(dict, "sigma_disp_um");
    osa = PyDict_GetItemString(dict, "sigma_angle_urad");
    for (int a = 0; a < 3; ++a)
        m[a] = PyDict_GetItemString(dict, keys[a]);
    if (!on || !os || !od1 || !od2 || !m[0] || !m[1] || !m[2]) {
        PyErr_SetString(sc_py_error, "a profile measurement needs n, s_mm, d1, d2 and the three sensors "
                                     "(use selfcal.ProfileMeasurement)");
        return -1;
    }
    if (as_int(on, "n", &n) || as_int(od1, "d1", &d1) || as_int(od2, "d2", &d2))
        return -1;
    s_mm = PyFloat_AsDouble(os);
    if (PyErr_Occurred() || opt_noise(osd ? osd : Py_None, "sigma_disp_um", &sd) ||
        opt_noise(osa ? osa : Py_None, "sigma_angle_urad", &sa))
        return -1;
    sc_error err;
    sc_error_clear(&err);
    if (sc_profile_data_init(d, n, s_mm, d1, d2, &err) != SC_OK) {
        raise_sc(&err);
        return -1;
    }
    double *dst[3][2] = {{d->m1_um[0], d->m1_um[1]}, {d->m2_um[0], d->m2_um[1]},
                         {d->m3_urad[0], d->m3_urad[1]}};
    for (int a = 0; a < 3; ++a) {
        if (!PySequence_Check(m[a]) || PySequence_Size(m[a]) != 2) {
            PyErr_Format(sc_py_error, "%s must hold the two scans' arrays", keys[a]);
            goto fail;
        }
        for (int k = 0; k < 2; ++k) {
            PyObject *it = PySequence_GetItem(m[a], k);
            char what[32];
            snprintf(what, sizeof what, "%s of scan %d", keys[a], k + 1);
            int rc = it ? copy_vec(it, dst[a][k], n - d->d[k], what) : -1;
            Py_XDECREF(it);
            if (rc)
                goto fail;
        }
    }
    d->has_sigma_disp = !isnan(sd);
    d->sigma_disp_um = d->has_sigma_disp ? sd : 0;
    d->has_sigma_angle = !isnan(sa);
    d->sigma_angle_urad = d->has_sigma_angle ? sa : 0;
    return 0;
fail:
    sc_profile_data_free(d);
    return -1;
}

/* A profile measurement from a path (read strictly, as the command line) or a dict. */
static int profile_source(PyObject *src, sc_profile_data *d)
{
    PyObject *path = as_path(src);
    if (PyErr_Occurred())
        return -1;
    if (!path)
        return profile_from_dict(src, d);
    sc_error err;
    sc_error_clear(&err);
    sc_status st;
    Py_BEGIN_ALLOW_THREADS
    st = sc_profile_read(PyBytes_AS_STRING(path), d, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(path);
    if (st != SC_OK) {
        raise_sc(&err);
        return -1;
    }
    return 0;
}

static PyObject *py_profile_read(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *src;
    if (!PyArg_ParseTuple(args, "O", &src))
        return NULL;
    sc_profile_data d;
    if (profile_source(src, &d))
        return NULL;
    PyObject *r = profile_to_dict(&d);
    sc_profile_data_free(&d);
    return r;
}

/* profile_check(dict): a measurement dict checked as the library checks it: None or raises. */
static PyObject *py_profile_check(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *src;
    if (!PyArg_ParseTuple(args, "O!", &PyDict_Type, &src))
        return NULL;
    sc_profile_data d;
    if (profile_from_dict(src, &d))
        return NULL;
    sc_profile_data_free(&d);
    Py_RETURN_NONE;
}

static PyObject *py_profile_write(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *pathobj, *dict;
    if (!PyArg_ParseTuple(args, "O&O", PyUnicode_FSConverter, &pathobj, &dict))
        return NULL;
    sc_profile_data d;
    PyObject *ret = NULL;
    if (profile_from_dict(dict, &d) == 0) {
        sc_error err;
        sc_error_clear(&err);
        sc_status st;
        Py_BEGIN_ALLOW_THREADS
        st = sc_profile_write(PyBytes_AS_STRING(pathobj), &d, &err);
        Py_END_ALLOW_THREADS
        if (st != SC_OK)
            raise_sc(&err);
        else
            ret = Py_NewRef(Py_None);
        sc_profile_data_free(&d);
    }
    Py_DECREF(pathobj);
    return ret;
}

/* profile_calibrate(src, method, sigma_disp_um, sigma_angle_urad, mc_trials, seed) -> dict */
static PyObject *py_profile_calibrate(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *src, *osd, *osa;
    int method;
    long mc;
    unsigned long long seed;
    if (!PyArg_ParseTuple(args, "OiOOlK", &src, &method, &osd, &osa, &mc, &seed))
        return NULL;
    sc_profile_options o;
    sc_profile_options_default(&o);
    o.method = method ? SC_PROFILE_LSQ : SC_PROFILE_DFT;
    o.mc_trials = mc;
    o.mc_seed = seed;
    if (opt_noise(osd, "sigma_disp_um", &o.sigma_disp_um) ||
        opt_noise(osa, "sigma_angle_urad", &o.sigma_angle_urad))
        return NULL;
    if (mc < 0 || mc == 1 || mc > 100000000) { /* as the command line's --mc */
        PyErr_Format(sc_py_error, "mc_trials must be 0 (analytic) or 2..100000000, got %ld", mc);
        return NULL;
    }
    sc_profile_data d;
    if (profile_source(src, &d))
        return NULL;
    const npy_intp n = d.n;
    PyArrayObject *f = new_vec(n, NPY_DOUBLE), *uf = new_vec(n, NPY_DOUBLE),
                  *ey = new_vec(n, NPY_DOUBLE), *x = new_vec(n, NPY_DOUBLE);
    PyObject *ret = NULL;
    if (!f || !uf || !ey || !x)
        goto done;
    for (npy_intp i = 0; i < n; ++i)
        ((double *)PyArray_DATA(x))[i] = (double)i * d.s_mm;
    sc_profile_solution s = {.f_um = PyArray_DATA(f), .uf_um = PyArray_DATA(uf),
                             .ey_um = PyArray_DATA(ey)};
    sc_error err;
    sc_error_clear(&err);
    sc_status st;
    Py_BEGIN_ALLOW_THREADS
    st = sc_profile_calibrate(&d, &o, &s, &err);
    Py_END_ALLOW_THREADS
    if (st != SC_OK) {
        raise_sc(&err);
        goto done;
    }
    ret = Py_BuildValue("{s:O,s:O,s:O,s:O,s:i,s:i,s:d,s:d,s:d,s:d,s:d,s:i,s:d,s:i,s:d,s:i,s:i}",
                        "x_mm", x, "f_um", f, "uf_um", uf, "ey_um", ey, "have_uf", s.have_uf,
                        "noise_known", s.noise_known, "sigma_disp_um", s.sigma_disp_um,
                        "sigma_angle_urad", s.sigma_angle_urad, "sigma_y1_um", s.sigma_y_um[0],
                        "sigma_y2_um", s.sigma_y_um[1], "wrss", s.wrss, "dof", s.dof,
                        "residual_ratio", s.residual_ratio, "n", d.n, "s_mm", d.s_mm, "d1",
                        d.d[0], "d2", d.d[1]);
done:
    Py_XDECREF(f);
    Py_XDECREF(uf);
    Py_XDECREF(ey);
    Py_XDECREF(x);
    sc_profile_data_free(&d);
    return ret;
}

/* profile_simulate(params, f_um or None, amp_um, harmonics, dabam_path or None)
 *   -> (measurement dict, f_um, ey_um (N - d1 values, relative to their least-squares line)) */
static PyObject *py_profile_simulate(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *params, *fobj, *dabam;
    double amp;
    int harmonics;
    if (!PyArg_ParseTuple(args, "O!OdiO", &PyDict_Type, &params, &fobj, &amp, &harmonics, &dabam))
        return NULL;
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    struct { const char *key; double *dst; } dkeys[] = {
        {"s_mm", &p.s_mm}, {"sigma_disp_um", &p.sigma_disp_um},
        {"sigma_angle_urad", &p.sigma_angle_urad}, {"ey_amp_um", &p.ey_amp_um},
        {"ep_amp_urad", &p.ep_amp_urad}, {"u1_um", &p.u1_um}, {"u2_um", &p.u2_um},
        {"u3_urad", &p.u3_urad}, {"b0_um", &p.b0_um}};
    for (size_t k = 0; k < sizeof dkeys / sizeof dkeys[0]; ++k) {
        PyObject *v = PyDict_GetItemString(params, dkeys[k].key);
        if (v && opt_double(v, dkeys[k].dst))
            return NULL;
    }
    struct { const char *key; int *dst; } ikeys[] = {
        {"n", &p.n}, {"d1", &p.d1}, {"d2", &p.d2}, {"write_sigma", &p.write_sigma}};
    for (size_t k = 0; k < sizeof ikeys / sizeof ikeys[0]; ++k) {
        PyObject *v = PyDict_GetItemString(params, ikeys[k].key);
        if (v && as_int(v, ikeys[k].key, ikeys[k].dst))
            return NULL;
    }
    PyObject *vs = PyDict_GetItemString(params, "seed");
    if (vs) {
        p.seed = PyLong_AsUnsignedLongLong(vs);
        if (PyErr_Occurred())
            return NULL;
    }
    if (p.n < 2 || p.n > 100000000) {
        PyErr_Format(sc_py_error, "N = %d is out of range", p.n);
        return NULL;
    }
    const npy_intp n = p.n;
    PyArrayObject *f = new_vec(n, NPY_DOUBLE), *ey = new_vec(n, NPY_DOUBLE);
    PyObject *ret = NULL, *meas = NULL, *path = NULL;
    sc_profile_data d;
    memset(&d, 0, sizeof d);
    sc_error err;
    sc_error_clear(&err);
    if (!f || !ey)
        goto done;
    double *fv = PyArray_DATA(f), *eyv = PyArray_DATA(ey);
    if (dabam != Py_None) {
        if (!PyUnicode_FSConverter(dabam, &path))
            goto done;
        if (sc_profile_load_dabam(PyBytes_AS_STRING(path), p.n, p.s_mm, fv, NULL, 0, &err) != SC_OK) {
            raise_sc(&err);
            goto done;
        }
    } else if (fobj != Py_None) {
        if (copy_vec(fobj, fv, n, "f_um"))
            goto done;
    } else {
        if (harmonics < 1 || harmonics > 100000 || !(amp >= 0) || !isfinite(amp)) {
            error_printf("harmonics must be 1..100000 and amp_um a finite number >= 0 (as the "
                         "command line's), got %d and %g", harmonics, amp);
            goto done;
        }
        sc_profile_sim_random_truth(&p, amp, harmonics, fv);
    }
    if (sc_profile_simulate(&p, fv, &d, eyv, &err) != SC_OK) {
        raise_sc(&err);
        goto done;
    }
    sc_profile_remove_line(p.n - p.d1, eyv);
    meas = profile_to_dict(&d);
    if (meas) {
        PyObject *eyc = vec_from(eyv, n - p.d1);
        if (eyc)
            ret = Py_BuildValue("(NON)", meas, f, eyc);
        else
            Py_DECREF(meas);
    }
done:
    Py_XDECREF(path);
    Py_XDECREF(f);
    Py_XDECREF(ey);
    sc_profile_data_free(&d);
    return ret;
}

/* ---- grid plates ---- */

/* An n-dimensional float64 array of the given shape, copied from v (or NaN-filled if v is NULL). */
static PyObject *arr_from(const double *v, int nd, const npy_intp *shape)
{
    PyArrayObject *a = (PyArrayObject *)PyArray_SimpleNew(nd, (npy_intp *)shape, NPY_DOUBLE);
    if (!a)
        return NULL;
    npy_intp n = PyArray_SIZE(a);
    double *dst = PyArray_DATA(a);
    for (npy_intp k = 0; k < n; ++k)
        dst[k] = v ? v[k] : NAN;
    return (PyObject *)a;
}

/* The plan as a dict: n, pitch_mm, origin_mm, stage (nx, ny), views (rot, shift, rows, cols,
 * sigma_um; rows/cols None when the view measures every mark on the stage). */
static PyObject *plan_to_dict(const sc_grid_plan *p)
{
    PyObject *views = PyList_New(p->n_views);
    if (!views)
        return NULL;
    for (int v = 0; v < p->n_views; ++v) {
        const sc_grid_view *w = &p->view[v];
        PyObject *rows = Py_None, *cols = Py_None;
        Py_INCREF(Py_None);
        Py_INCREF(Py_None);
        if (w->restricted) {
            Py_DECREF(rows);
            Py_DECREF(cols);
            rows = PyList_New(0);
            cols = PyList_New(0);
            for (int k = 0; rows && cols && k < p->n; ++k) {
                if (w->row_sel[k])
                    PyList_Append(rows, PyLong_FromLong(k)); /* small ints are cached */
                if (w->col_sel[k])
                    PyList_Append(cols, PyLong_FromLong(k));
            }
        }
        PyObject *sig = w->sigma_um > 0 ? PyFloat_FromDouble(w->sigma_um) : Py_NewRef(Py_None);
        PyObject *tc = p->scale.has_temps ? PyFloat_FromDouble(w->temp_C) : Py_NewRef(Py_None);
        PyObject *d = (rows && cols && sig && tc)
                          ? Py_BuildValue("{s:i,s:(ii),s:N,s:N,s:N,s:N}", "rot", w->rot_deg,
                                          "shift", w->shift_x, w->shift_y, "rows", rows, "cols",
                                          cols, "sigma_um", sig, "temp_C", tc)
                          : NULL;
        if (!d) {
            Py_DECREF(views);
            return NULL;
        }
        PyList_SET_ITEM(views, v, d);
    }
    const sc_grid_scale *sc = &p->scale;
    PyObject *E = sc->has_plate_scale
                      ? Py_BuildValue("(dd)", sc->plate_scale_ppm, sc->u_plate_scale_ppm)
                      : Py_NewRef(Py_None);
    PyObject *A = sc->has_cte ? Py_BuildValue("(dd)", sc->cte_ppm_per_K, sc->u_cte_ppm_per_K)
                              : Py_NewRef(Py_None);
    if (!E || !A) {
        Py_XDECREF(E), Py_XDECREF(A), Py_DECREF(views);
        return NULL;
    }
    return Py_BuildValue("{s:i,s:d,s:(dd),s:(ii),s:N,s:N,s:N,s:d}", "n", p->n, "pitch_mm",
                         p->pitch_mm, "origin_mm", p->origin_mm[0], p->origin_mm[1], "stage",
                         sc_grid_stage_nx(p), sc_grid_stage_ny(p), "views", views,
                         "plate_scale_ppm", E, "plate_cte_ppm_per_K", A, "temp_u_K",
                         sc->has_temps ? sc->temp_u_K : SC_GRID_TEMP_U_K_DEFAULT);
}

/* The scale lines (SPEC §11) of a plan dict: plate_scale_ppm and plate_cte_ppm_per_K as (value,
 * u) or None, temp_u_K, and temp_C on every view or none (checked by sc_grid_plan_check). */
static int scale_from_dict(PyObject *dict, PyObject *views, sc_grid_plan *p)
{
    sc_grid_scale *sc = &p->scale;
    PyObject *E = PyDict_GetItemString(dict, "plate_scale_ppm"),
             *A = PyDict_GetItemString(dict, "plate_cte_ppm_per_K"),
             *U = PyDict_GetItemString(dict, "temp_u_K");
    if (E && E != Py_None) {
        if (!PyArg_ParseTuple(E, "dd", &sc->plate_scale_ppm, &sc->u_plate_scale_ppm))
            return -1;
        sc->has_plate_scale = 1;
    }
    if (A && A != Py_None) {
        if (!PyArg_ParseTuple(A, "dd", &sc->cte_ppm_per_K, &sc->u_cte_ppm_per_K))
            return -1;
        sc->has_cte = 1;
    }
    sc->temp_u_K = U && U != Py_None ? PyFloat_AsDouble(U) : SC_GRID_TEMP_U_K_DEFAULT;
    int with = 0;
    for (int v = 0; v < p->n_views; ++v) {
        PyObject *w = PySequence_Fast_GET_ITEM(views, v);
        PyObject *t = PyDict_GetItemString(w, "temp_C");
        if (t && t != Py_None) {
            p->view[v].temp_C = PyFloat_AsDouble(t);
            ++with;
        }
    }
    if (PyErr_Occurred())
        return -1;
    if (with && with != p->n_views) {
        PyErr_SetString(sc_py_error, "temp_C must be given on every view or on none");
        return -1;
    }
    sc->has_temps = with > 0;
    return 0;
}

/* An index list (rows= or cols=) into sel[n]; -1 with an exception. */
static int index_list(PyObject *o, unsigned char *sel, int n, const char *what)
{
    PyObject *seq = PySequence_Fast(o, what);
    if (!seq)
        return -1;
    for (Py_ssize_t k = 0; k < PySequence_Fast_GET_SIZE(seq); ++k) {
        long i = PyLong_AsLong(PySequence_Fast_GET_ITEM(seq, k));
        if (PyErr_Occurred() || i < 0 || i >= n) {
            Py_DECREF(seq);
            if (!PyErr_Occurred())
                PyErr_Format(sc_py_error, "%s index %ld outside the plate (0..%d)", what, i, n - 1);
            return -1;
        }
        sel[i] = 1;
    }
    Py_DECREF(seq);
    return 0;
}

static int plan_from_dict_in(PyObject *dict, sc_grid_plan *p);

/* A plan from a dict as plan_to_dict makes (stage and views' rows/cols/sigma_um optional);
 * checked by the library. -1 with an exception (p then holds no views). */
static int plan_from_dict(PyObject *dict, sc_grid_plan *p)
{
    memset(p, 0, sizeof *p);
    int rc = plan_from_dict_in(dict, p);
    if (rc)
        sc_grid_plan_free(p);
    return rc;
}

static int plan_from_dict_in(PyObject *dict, sc_grid_plan *p)
{
    if (!PyDict_Check(dict)) {
        PyErr_SetString(sc_py_error, "a grid plan is needed (use selfcal.GridPlan)");
        return -1;
    }
    PyObject *on = PyDict_GetItemString(dict, "n"), *op = PyDict_GetItemString(dict, "pitch_mm"),
             *oo = PyDict_GetItemString(dict, "origin_mm"), *os = PyDict_GetItemString(dict, "stage"),
             *ov = PyDict_GetItemString(dict, "views");
    if (!on || !op || !ov) {
        PyErr_SetString(sc_py_error, "a grid plan needs n, pitch_mm and views (use selfcal.GridPlan)");
        return -1;
    }
    if (as_int(on, "n", &p->n))
        return -1;
    p->pitch_mm = PyFloat_AsDouble(op);
    if (oo && oo != Py_None && !PyArg_ParseTuple(oo, "dd", &p->origin_mm[0], &p->origin_mm[1]))
        return -1;
    if (os && os != Py_None && !PyArg_ParseTuple(os, "ii", &p->stage_nx, &p->stage_ny))
        return -1;
    if (PyErr_Occurred())
        return -1;
    if (p->stage_nx == p->n && p->stage_ny == p->n)
        p->stage_nx = p->stage_ny = 0; /* the plate's own grid */
    if (p->n < 3 || p->n > SC_GRID_MAX_N) {
        PyErr_Format(sc_py_error, "N = %d is out of range (3..%d)", p->n, SC_GRID_MAX_N);
        return -1;
    }
    PyObject *views = PySequence_Fast(ov, "views must be a sequence");
    if (!views)
        return -1;
    Py_ssize_t nv = PySequence_Fast_GET_SIZE(views);
    if (nv < 1 || nv > SC_GRID_VIEW_LIMIT) {
        Py_DECREF(views);
        PyErr_Format(sc_py_error, "a plan has 1 to %d views, not %zd", SC_GRID_VIEW_LIMIT, nv);
        return -1;
    }
    sc_error verr;
    sc_error_clear(&verr);
    if (sc_grid_plan_views(p, (int)nv, &verr) != SC_OK) {
        Py_DECREF(views);
        raise_sc(&verr);
        return -1;
    }
    for (int v = 0; v < p->n_views; ++v) {
        PyObject *w = PySequence_Fast_GET_ITEM(views, v);
        sc_grid_view *g = &p->view[v];
        PyObject *r = PyDict_Check(w) ? PyDict_GetItemString(w, "rot") : NULL,
                 *sh = PyDict_Check(w) ? PyDict_GetItemString(w, "shift") : NULL;
        if (!r || !sh) {
            Py_DECREF(views);
            PyErr_SetString(sc_py_error, "a view is a dict with rot and shift");
            return -1;
        }
        if (as_int(r, "rot", &g->rot_deg) || !PyArg_ParseTuple(sh, "ii", &g->shift_x, &g->shift_y)) {
            Py_DECREF(views);
            return -1;
        }
        PyObject *rows = PyDict_GetItemString(w, "rows"), *cols = PyDict_GetItemString(w, "cols"),
                 *sig = PyDict_GetItemString(w, "sigma_um");
        if ((rows && rows != Py_None) || (cols && cols != Py_None)) {
            g->restricted = 1;
            if ((rows && rows != Py_None && index_list(rows, g->row_sel, p->n, "rows")) ||
                (cols && cols != Py_None && index_list(cols, g->col_sel, p->n, "cols"))) {
                Py_DECREF(views);
                return -1;
            }
        }
        if (sig && sig != Py_None) {
            g->sigma_um = PyFloat_AsDouble(sig);
            if (PyErr_Occurred() || !(g->sigma_um > 0)) {
                Py_DECREF(views);
                if (!PyErr_Occurred())
                    PyErr_Format(sc_py_error, "view %d: sigma_um must be positive", v);
                return -1;
            }
        }
    }
    int bad = scale_from_dict(dict, views, p);
    Py_DECREF(views);
    if (bad)
        return -1;
    sc_error err;
    sc_error_clear(&err);
    if (sc_grid_plan_check(p, &err) != SC_OK) {
        raise_sc(&err);
        return -1;
    }
    return 0;
}

/* Nominal stage position (mm) of mark (i, j) in view v; 0 if the mark is off the stage. */
static int nominal_mm(const sc_grid_plan *p, int v, int i, int j, double *x, double *y)
{
    int ni, nj;
    if (!sc_grid_mark_node(p, v, i, j, &ni, &nj))
        return 0;
    sc_grid_node_xy_mm(p, ni, nj, x, y);
    *x += p->origin_mm[0];
    *y += p->origin_mm[1];
    return 1;
}

/* The measurement as a dict: plan, x_mm, y_mm (views x N x N, NaN where not measured), and
 * ux_um, uy_um, t_s when the data have them (else None). */
static PyObject *data_to_dict(const sc_grid_data *d)
{
    const sc_grid_plan *p = &d->plan;
    int n = p->n, nv = p->n_views;
    npy_intp shape[3] = {nv, n, n};
    PyObject *x = arr_from(NULL, 3, shape), *y = arr_from(NULL, 3, shape);
    PyObject *opt[3] = {Py_NewRef(Py_None), Py_NewRef(Py_None), Py_NewRef(Py_None)};
    double *const *src[3] = {d->ux_um, d->uy_um, d->t_s};
    for (int q = 0; q < 3; ++q) {
        int any = 0;
        for (int v = 0; src[q] && v < nv; ++v)
            any |= src[q][v] != NULL;
        if (!any)
            continue;
        Py_DECREF(opt[q]);
        opt[q] = arr_from(NULL, 3, shape);
        if (!opt[q])
            break;
        double *o = PyArray_DATA((PyArrayObject *)opt[q]);
        for (int v = 0; v < nv; ++v)
            for (long k = 0; src[q][v] && k < (long)n * n; ++k)
                o[(long)v * n * n + k] = src[q][v][k];
    }
    PyObject *plan = plan_to_dict(p);
    if (!x || !y || !opt[0] || !opt[1] || !opt[2] || !plan) {
        Py_XDECREF(x), Py_XDECREF(y), Py_XDECREF(plan);
        for (int q = 0; q < 3; ++q)
            Py_XDECREF(opt[q]);
        return NULL;
    }
    double *xv = PyArray_DATA((PyArrayObject *)x), *yv = PyArray_DATA((PyArrayObject *)y);
    for (int v = 0; v < nv; ++v)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                long k = (long)i * n + j, o = (long)v * n * n + k;
                double nx, ny;
                if (!isfinite(d->dx_um[v][k]) || !nominal_mm(p, v, i, j, &nx, &ny))
                    continue;
                xv[o] = nx + d->dx_um[v][k] / 1000.0;
                yv[o] = ny + d->dy_um[v][k] / 1000.0;
            }
    return Py_BuildValue("{s:N,s:N,s:N,s:N,s:N,s:N}", "plan", plan, "x_mm", x, "y_mm", y, "ux_um",
                         opt[0], "uy_um", opt[1], "t_s", opt[2]);
}

/* A (views, N, N) float64 array from a dict entry into per-view arrays of d (allocated). */
static int fill_views(PyObject *dict, const char *key, const sc_grid_plan *p, double **dst,
                      const double *sub, double scale)
{
    PyObject *o = PyDict_GetItemString(dict, key);
    PyArrayObject *a = o ? (PyArrayObject *)PyArray_FROMANY(o, NPY_DOUBLE, 3, 3, NPY_ARRAY_IN_ARRAY) : NULL;
    if (!a) { /* numpy's own ValueError/TypeError: said as the others, a selfcal.Error */
        PyErr_Clear();
        PyErr_Format(sc_py_error, "%s must be numbers of the shape (views, N, N) = (%d, %d, %d)",
                     key, p->n_views, p->n, p->n);
        return -1;
    }
    int n = p->n;
    if (PyArray_DIM(a, 0) != p->n_views || PyArray_DIM(a, 1) != n || PyArray_DIM(a, 2) != n) {
        PyErr_Format(sc_py_error, "%s must have the shape (views, N, N) = (%d, %d, %d)", key,
                     p->n_views, n, n);
        Py_DECREF(a);
        return -1;
    }
    const double *src = PyArray_DATA(a);
    for (int v = 0; v < p->n_views; ++v)
        for (long k = 0; k < (long)n * n; ++k) {
            double val = src[(long)v * n * n + k];
            /* NaN: not measured; anything else must be a number (and a mark the view places on
             * the stage, where a nominal position is subtracted) */
            if (isinf(val) || (sub && !isnan(val) && isnan(sub[(long)v * n * n + k]))) {
                PyErr_Format(sc_py_error, isinf(val) ? "%s[%d, %ld, %ld] is infinite (NaN: not measured)"
                                                     : "%s[%d, %ld, %ld] is given but view %d does "
                                                       "not place that mark on the stage",
                             key, v, k / n, k % n, v);
                Py_DECREF(a);
                return -1;
            }
            dst[v][k] = sub ? (val - sub[(long)v * n * n + k]) * scale : val;
        }
    Py_DECREF(a);
    return 0;
}

/* d (allocated here) from a measurement dict; -1 with an exception. */
static int data_from_dict(PyObject *dict, sc_grid_data *d)
{
    memset(d, 0, sizeof *d);
    PyObject *plan = PyDict_Check(dict) ? PyDict_GetItemString(dict, "plan") : NULL;
    if (!plan) {
        PyErr_SetString(sc_py_error, "a grid measurement file path or a selfcal.GridMeasurement is "
                                     "needed");
        return -1;
    }
    if (plan_from_dict(plan, &d->plan))
        return -1;
    const sc_grid_plan *p = &d->plan;
    PyObject *ux = PyDict_GetItemString(dict, "ux_um"), *ts = PyDict_GetItemString(dict, "t_s");
    int weights = ux && ux != Py_None, times = ts && ts != Py_None;
    sc_error err;
    sc_error_clear(&err);
    if (sc_grid_data_alloc(d, &err) != SC_OK ||
        ((weights || times) && sc_grid_data_alloc_extra(d, weights, times, &err) != SC_OK)) {
        sc_grid_data_free(d);
        raise_sc(&err);
        return -1;
    }
    int n = p->n;
    size_t tot = (size_t)p->n_views * n * n;
    double *nom = malloc(2 * tot * sizeof(double) + 1);
    if (!nom) {
        sc_grid_data_free(d);
        PyErr_NoMemory();
        return -1;
    }
    for (int v = 0; v < p->n_views; ++v)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                size_t o = ((size_t)v * n + i) * n + j;
                if (!nominal_mm(p, v, i, j, &nom[o], &nom[tot + o]))
                    nom[o] = nom[tot + o] = NAN;
            }
    int rc = fill_views(dict, "x_mm", p, d->dx_um, nom, 1000.0) ||
             fill_views(dict, "y_mm", p, d->dy_um, nom + tot, 1000.0) ||
             (weights && (fill_views(dict, "ux_um", p, d->ux_um, NULL, 1) ||
                          fill_views(dict, "uy_um", p, d->uy_um, NULL, 1))) ||
             (times && fill_views(dict, "t_s", p, d->t_s, NULL, 1));
    free(nom);
    for (int v = 0; !rc && v < p->n_views; ++v)
        for (int i = 0; i < n && !rc; ++i)
            for (int j = 0; j < n && !rc; ++j) {
                long k = (long)i * n + j;
                int fx = isfinite(d->dx_um[v][k]), fy = isfinite(d->dy_um[v][k]);
                if (fx != fy) {
                    PyErr_Format(sc_py_error, "view %d mark (%d,%d): x_mm and y_mm must both be "
                                 "measured or both NaN", v, i, j);
                    rc = -1;
                } else if (fx && !sc_grid_view_measures(p, v, i, j)) {
                    PyErr_Format(sc_py_error, "view %d mark (%d,%d) is measured but the view does "
                                 "not place it on a stage node it measures", v, i, j);
                    rc = -1;
                } else if (fx && fmax(fabs(d->dx_um[v][k]), fabs(d->dy_um[v][k])) >
                                     500.0 * p->pitch_mm) {
                    PyErr_Format(sc_py_error, "view %d mark (%d,%d) is more than half a pitch from "
                                 "its nominal position", v, i, j);
                    rc = -1;
                }
            }
    if (rc)
        sc_grid_data_free(d);
    return rc;
}

/* A grid measurement from a path (read strictly, as the command line) or a dict; info is
 * filled for a file (else zeroed), *path_out gets the path bytes (or NULL). */
static int grid_source(PyObject *src, sc_grid_data *d, sc_grid_file_info *info, PyObject **path_out)
{
    memset(info, 0, sizeof *info);
    *path_out = NULL;
    PyObject *path = as_path(src);
    if (PyErr_Occurred())
        return -1;
    if (!path)
        return data_from_dict(src, d);
    sc_error err;
    sc_error_clear(&err);
    sc_status st;
    Py_BEGIN_ALLOW_THREADS
    st = sc_grid_read(PyBytes_AS_STRING(path), d, info, &err);
    Py_END_ALLOW_THREADS
    if (st != SC_OK) {
        Py_DECREF(path);
        raise_sc(&err);
        return -1;
    }
    *path_out = path;
    return 0;
}

static PyObject *py_grid_read(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *src, *path;
    if (!PyArg_ParseTuple(args, "O", &src))
        return NULL;
    sc_grid_data d;
    sc_grid_file_info info;
    if (grid_source(src, &d, &info, &path))
        return NULL;
    Py_XDECREF(path);
    sc_grid_file_info_free(&info);
    PyObject *r = data_to_dict(&d);
    sc_grid_data_free(&d);
    return r;
}

/* grid_check(dict): a plan dict (no "plan" key) or a measurement dict checked as the library
 * checks it, nothing solved (no CHOLMOD): None, or the exception a calibration would raise. */
static PyObject *py_grid_check(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *src;
    if (!PyArg_ParseTuple(args, "O!", &PyDict_Type, &src))
        return NULL;
    if (!PyDict_GetItemString(src, "plan")) {
        sc_grid_plan p;
        if (plan_from_dict(src, &p))
            return NULL;
        sc_grid_plan_free(&p);
    } else {
        sc_grid_data d;
        if (data_from_dict(src, &d))
            return NULL;
        sc_grid_data_free(&d);
    }
    Py_RETURN_NONE;
}

static PyObject *py_grid_write(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *pathobj, *dict;
    if (!PyArg_ParseTuple(args, "O&O", PyUnicode_FSConverter, &pathobj, &dict))
        return NULL;
    sc_grid_data d;
    PyObject *ret = NULL;
    if (data_from_dict(dict, &d) == 0) {
        sc_error err;
        sc_error_clear(&err);
        if (sc_grid_write_input(PyBytes_AS_STRING(pathobj), &d, &err) != SC_OK)
            raise_sc(&err);
        else
            ret = Py_NewRef(Py_None);
        sc_grid_data_free(&d);
    }
    Py_DECREF(pathobj);
    return ret;
}

/* grid_plan(src): src a path (plan or data file), a plan dict or a measurement dict. */
static PyObject *py_grid_plan(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *src, *path = NULL;
    if (!PyArg_ParseTuple(args, "O", &src))
        return NULL;
    sc_grid_data d;
    sc_grid_file_info info;
    int has_data;
    memset(&d, 0, sizeof d);
    memset(&info, 0, sizeof info);
    if (PyDict_Check(src) && !PyDict_GetItemString(src, "plan")) { /* a bare plan */
        if (plan_from_dict(src, &d.plan))
            return NULL;
        has_data = 0;
    } else {
        if (grid_source(src, &d, &info, &path))
            return NULL;
        has_data = path ? info.n_rows > 0 : 1;
    }
    sc_error err;
    sc_error_clear(&err);
    sc_grid_lsq_plan *q = NULL;
    PyObject *ret = NULL, *sgx = NULL, *sgy = NULL;
    sc_status st;
    /* pass 0: the plan as it states its uncertainties; pass 1, where it states some: std(G) in
     * µm kept from pass 0, the ratios per unit σ_r from the same plan with equal weights (as
     * `selfcal plan`); one plan in memory at a time, the last one's per-node ratios below */
    sc_grid_lsq_info qi, unit;
    double c_rms_um = NAN, c_max_um = NAN;
    for (int pass = 0; pass < 2; ++pass) {
        sc_grid_lsq_opts po = {.unit_weights = pass};
        Py_BEGIN_ALLOW_THREADS
        st = sc_grid_lsq_plan_create(&d.plan, has_data ? &d : NULL, &po, &q, &err);
        Py_END_ALLOW_THREADS
        if (st != SC_OK) {
            if (!err.file[0] && path) {
                snprintf(err.file, sizeof err.file, "%s", PyBytes_AS_STRING(path));
                err.line = info.header_end_line;
            }
            raise_sc(&err);
            goto done;
        }
        sc_grid_lsq_get_info(q, pass ? &unit : &qi);
        if (pass == 0)
            unit = qi;
        if (!(qi.weighted && qi.identifiable))
            break;
        if (pass == 0) {
            c_rms_um = qi.sigma_c_ratio_rms;
            c_max_um = qi.sigma_c_ratio_max;
            sc_grid_lsq_plan_destroy(q);
            q = NULL;
        }
    }
    npy_intp shape[2] = {sc_grid_stage_ny(&d.plan), sc_grid_stage_nx(&d.plan)};
    sgx = arr_from(NULL, 2, shape);
    sgy = arr_from(NULL, 2, shape);
    if (!sgx || !sgy)
        goto done;
    if (qi.identifiable &&
        sc_grid_lsq_sigma_ratio(q, PyArray_DATA((PyArrayObject *)sgx),
                                PyArray_DATA((PyArrayObject *)sgy), &err) != SC_OK) {
        raise_sc(&err);
        goto done;
    }
    ret = Py_BuildValue("{s:O,s:l,s:d,s:d,s:d,s:d,s:l,s:l,s:l,s:l,s:O,s:O,s:N,s:l,s:l,s:d,s:d,s:d,s:d,s:l}",
                        "identifiable",
                        qi.identifiable ? Py_True : Py_False, "free", qi.identifiable ? 0L : qi.free_dof,
                        "sigma_c_ratio_rms", qi.identifiable ? unit.sigma_c_ratio_rms : INFINITY,
                        "sigma_c_ratio_max", qi.identifiable ? unit.sigma_c_ratio_max : INFINITY,
                        "sigma_c_rms_um", c_rms_um, "sigma_c_max_um", c_max_um,
                        "n_unknowns", qi.n_unknowns, "n_equations", qi.n_equations,
                        "n_constraints", qi.n_constraints, "n_stage_unmeasured",
                        qi.n_stage_unmeasured, "sigma_ratio_gx", sgx, "sigma_ratio_gy", sgy,
                        "plan", plan_to_dict(&d.plan), "n_testable", qi.n_testable,
                        "n_untestable", qi.n_untestable, "redundancy_min", qi.redundancy_min,
                        "redundancy_mean", qi.redundancy_mean, "mdb_ratio_max", qi.mdb_ratio_max,
                        "mdb_ratio_mean_r", qi.mdb_ratio_mean_r, "residual_dof",
                        qi.identifiable ? qi.residual_dof : -1L);
done:
    Py_XDECREF(sgx);
    Py_XDECREF(sgy);
    Py_XDECREF(path);
    sc_grid_lsq_plan_destroy(q);
    sc_grid_data_free(&d);
    sc_grid_file_info_free(&info);
    return ret;
}

/* Warnings of the calibration collected into a Python list; called during the solve, which runs
 * without the GIL: taken for the append. */
static void warn_collect(void *ctx, const char *msg)
{
    PyGILState_STATE g = PyGILState_Ensure();
    PyObject *s = PyUnicode_DecodeUTF8(msg, (Py_ssize_t)strlen(msg), "replace");
    if (s) {
        PyList_Append((PyObject *)ctx, s);
        Py_DECREF(s);
    } else {
        PyErr_Clear();
    }
    PyGILState_Release(g);
}

/* The per-view scalars of a result as a (views,) array. */
static PyObject *per_view(const double *v, int nv)
{
    npy_intp s[1] = {nv};
    return arr_from(v, 1, s);
}

static PyObject *solution_to_dict(const sc_grid_data *d, const sc_grid_solution *s, PyObject *warnings)
{
    const sc_grid_plan *p = &d->plan;
    const sc_grid_result *r = &s->res;
    int n = p->n, nv = p->n_views, nx = sc_grid_stage_nx(p), ny = sc_grid_stage_ny(p);
    npy_intp sg[2] = {ny, nx}, sa[2] = {n, n}, sr[3] = {nv, n, n}, sc[2] = {s->n_cov, s->n_cov};
    double *xy = malloc(2 * (size_t)nx * ny * sizeof(double));
    if (!xy)
        return PyErr_NoMemory();
    for (int i = 0; i < ny; ++i)
        for (int j = 0; j < nx; ++j) {
            sc_grid_node_xy_mm(p, i, j, &xy[i * nx + j], &xy[(size_t)nx * ny + i * nx + j]);
            xy[i * nx + j] += p->origin_mm[0];
            xy[(size_t)nx * ny + i * nx + j] += p->origin_mm[1];
        }
    PyObject *outlier = Py_None;
    Py_INCREF(Py_None);
    if (s->outlier) {
        Py_DECREF(outlier);
        outlier = PyArray_SimpleNew(3, sr, NPY_BOOL);
        if (outlier)
            for (size_t k = 0; k < (size_t)nv * n * n; ++k)
                ((npy_bool *)PyArray_DATA((PyArrayObject *)outlier))[k] = s->outlier[k] != 0;
    }
#define OPT(ptr, nd, shp) ((ptr) ? arr_from((ptr), (nd), (shp)) : Py_NewRef(Py_None))
    PyObject *ret = outlier ? Py_BuildValue(
        "{s:N,s:N,s:N,s:N,s:N,s:N,s:N,s:N,s:d,s:d,s:d,s:d,s:N,s:N,s:N,s:N,s:N,s:N,s:d,s:d,s:d,"
        "s:l,s:l,s:O,s:d,s:d,s:d,s:O,s:N,s:N,s:N,s:N,s:N,s:l,s:l,s:N,s:O,s:d,s:O,s:d,s:d,s:l,"
        "s:O,s:N,s:N,s:N,s:d,s:d,s:d,s:d}",
        "gx_um", arr_from(r->gx_um, 2, sg), "gy_um", arr_from(r->gy_um, 2, sg),
        "ugx_um", arr_from(r->ugx_um, 2, sg), "ugy_um", arr_from(r->ugy_um, 2, sg),
        "x_mm", arr_from(xy, 2, sg), "y_mm", arr_from(xy + (size_t)nx * ny, 2, sg),
        "ax_um", arr_from(r->ax_um, 2, sa), "ay_um", arr_from(r->ay_um, 2, sa),
        "O", r->O, "R", r->R, "uO", r->uO, "uR", r->uR,
        "tx_um", per_view(r->tx_um, nv), "ty_um", per_view(r->ty_um, nv),
        "theta_urad", per_view(r->theta_urad, nv), "utx_um", per_view(r->utx_um, nv),
        "uty_um", per_view(r->uty_um, nv), "utheta_urad", per_view(r->utheta_urad, nv),
        "residual_rms_um", r->residual_rms_um, "sigma_r_est_um", r->sigma_r_est_um,
        "sigma_r_used_um", r->sigma_r_used_um, "n_measurements", r->n_measurements, "dof", r->dof,
        "weighted", r->weighted ? Py_True : Py_False, "variance_factor", r->variance_factor,
        "chi2_lo", r->chi2_lo, "chi2_hi", r->chi2_hi, "chi2_pass", r->chi2_pass ? Py_True : Py_False,
        "rx_um", OPT(s->rx_um, 3, sr), "ry_um", OPT(s->ry_um, 3, sr), "tx", OPT(s->tx, 3, sr),
        "ty", OPT(s->ty, 3, sr), "outlier", outlier, "n_flagged", s->n_flagged, "n_removed",
        s->n_removed, "covariance_um2", OPT(s->cov_um2, 2, sc), "warnings", warnings,
        "outlier_alpha", r->outlier_alpha, "outlier_alpha_each",
        r->outlier_alpha_each ? Py_True : Py_False, "outlier_alpha_coord", r->outlier_alpha_coord,
        "outlier_crit", r->outlier_crit, "n_outlier_tests", r->n_outlier_tests,
        "view_noise_estimated", r->view_noise_estimated ? Py_True : Py_False,
        "view_sigma_um", per_view(r->view_sigma_um, nv),
        "view_noise_factor", per_view(r->view_noise_factor, nv),
        "view_sigma_u_um", per_view(r->view_sigma_u_um, nv), "O_urad", r->O * 1e6,
        "R_ppm", r->R * 1e6, "uO_urad", r->uO * 1e6, "uR_ppm", r->uR * 1e6) : NULL;
#undef OPT
    free(xy);
    return ret;
}

/* d[key] = v (v's reference taken); -1 on failure (v NULL). */
static int set_item(PyObject *d, const char *key, PyObject *v)
{
    if (!v)
        return -1;
    int rc = PyDict_SetItemString(d, key, v);
    Py_DECREF(v);
    return rc;
}

/* The budget (SPEC §11) as a dict: the scale model, the free view scales, the noise part of
 * u(G) and the table at the worst node. */
static PyObject *budget_to_dict(const sc_grid_plan *p, const sc_grid_budget *b)
{
    int nv = p->n_views, nx = sc_grid_stage_nx(p), ny = sc_grid_stage_ny(p);
    npy_intp sg[2] = {ny, nx};
    PyObject *d = PyDict_New(), *rows = PyList_New(0);
    if (!d || !rows) {
        Py_XDECREF(d), Py_XDECREF(rows);
        return NULL;
    }
    int mag = b->applies && b->magnification, bad = 0;
    bad |= set_item(d, "scale_included", PyBool_FromLong(mag));
    bad |= set_item(d, "magnification_ppm", PyFloat_FromDouble(mag ? b->magnification_ppm : NAN));
    bad |= set_item(d, "u_magnification_ppm",
                    PyFloat_FromDouble(mag ? b->u_magnification_ppm : NAN));
    bad |= set_item(d, "view_scale_free", PyBool_FromLong(b->applies && b->view_scale_free));
    for (int r = 0; b->applies && r < b->n_rows; ++r) {
        const sc_grid_budget_row *w = &b->row[r];
        PyObject *row = Py_BuildValue("{s:s,s:s,s:d,s:d,s:d,s:d}", "source", w->source, "unit",
                                      w->unit, "u", w->u, "sensitivity_um_per_unit", w->c,
                                      "contribution_um", w->contrib_um, "dof", w->dof);
        bad |= !row || PyList_Append(rows, row) != 0;
        Py_XDECREF(row);
    }
    if (b->applies) {
        bad |= set_item(d, "view_scale_ppm", per_view(b->view_scale_ppm, nv));
        bad |= set_item(d, "view_scale_free_ppm", per_view(b->view_scale_free_ppm, nv));
        bad |= set_item(d, "u_view_scale_free_ppm", per_view(b->u_view_scale_free_ppm, nv));
        bad |= set_item(d, "view_scale_significant", PyBool_FromLong(b->view_scale_significant));
    }
    if (b->applies && b->n_rows > 0) {
        bad |= set_item(d, "ugx_noise_um", arr_from(b->ugx_noise_um, 2, sg));
        bad |= set_item(d, "ugy_noise_um", arr_from(b->ugy_noise_um, 2, sg));
        bad |= set_item(d, "node", Py_BuildValue("(ll)", b->worst_node / nx, b->worst_node % nx));
        bad |= set_item(d, "component", PyUnicode_FromString(b->worst_comp ? "gy" : "gx"));
        bad |= set_item(d, "u_c_um", PyFloat_FromDouble(b->u_c_um));
        bad |= set_item(d, "nu_eff", PyFloat_FromDouble(b->nu_eff));
        bad |= set_item(d, "k", PyFloat_FromDouble(b->k));
        bad |= set_item(d, "k_from", PyUnicode_FromString(b->k_welch ? "welch-satterthwaite"
                                                                      : "2"));
        bad |= set_item(d, "U_um", PyFloat_FromDouble(b->U_um));
    }
    bad |= PyDict_SetItemString(d, "rows", rows) != 0;
    Py_DECREF(rows);
    if (bad) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

/* The Monte Carlo's figures as a dict. */
static PyObject *mc_to_dict(const sc_grid_plan *p, const sc_grid_mc *mc)
{
    npy_intp sg[2] = {sc_grid_stage_ny(p), sc_grid_stage_nx(p)};
    return Py_BuildValue("{s:l,s:K,s:i,s:d,s:N,s:N,s:N,s:N,s:N,s:N,s:N,s:N,s:d,s:d,s:d,s:d}",
                         "trials", mc->trials, "seed", (unsigned long long)mc->seed, "threads",
                         mc->threads, "seconds", mc->seconds, "ugx_um", arr_from(mc->ugx_um, 2, sg),
                         "ugy_um", arr_from(mc->ugy_um, 2, sg), "ratio_x",
                         arr_from(mc->ratio_x, 2, sg), "ratio_y", arr_from(mc->ratio_y, 2, sg),
                         "gx_lo_um", arr_from(mc->gx_lo_um, 2, sg), "gx_hi_um",
                         arr_from(mc->gx_hi_um, 2, sg), "gy_lo_um", arr_from(mc->gy_lo_um, 2, sg),
                         "gy_hi_um", arr_from(mc->gy_hi_um, 2, sg), "ratio_min", mc->ratio_min,
                         "ratio_max", mc->ratio_max, "ratio_mean", mc->ratio_mean,
                         "magnification_sd_ppm", mc->magnification_sd_ppm);
}

/* The caller's progress function (a Python callable, called with the GIL taken): its first
 * exception is kept and raised after the solve, and it is not called again. */
typedef struct progress_ctx {
    PyObject *fn;
    PyObject *exc_type, *exc_value, *exc_tb;
} progress_ctx;

static void progress_call(void *ctx, const char *phase, double done, double total, double peak)
{
    progress_ctx *c = ctx;
    PyGILState_STATE g = PyGILState_Ensure();
    if (!c->exc_type) {
        PyObject *r = PyObject_CallFunction(c->fn, "sddd", phase, done, total, peak);
        if (!r)
            PyErr_Fetch(&c->exc_type, &c->exc_value, &c->exc_tb);
        Py_XDECREF(r);
    }
    PyGILState_Release(g);
}

/* grid_calibrate(src, method, sigma_r_um, drift, reject_outliers, covariance, outlier_alpha,
 * outlier_alpha_each, estimate_view_noise, view_scale_free, mc_trials, mc_seed[, progress,
 * max_bytes, solver, node_sigma, node_sigma_sample]) -> dict (the last three: sc_grid_options') */
static PyObject *py_grid_calibrate(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *src, *path;
    sc_grid_options o;
    sc_grid_options_default(&o);
    int method;
    long mc_trials;
    unsigned long long mc_seed;
    PyObject *progress = Py_None;
    double max_bytes = 0;
    if (!PyArg_ParseTuple(args, "OidpppdppplK|Odiii", &src, &method, &o.sigma_r_um, &o.drift,
                          &o.reject_outliers, &o.covariance, &o.outlier_alpha,
                          &o.outlier_alpha_each, &o.estimate_view_noise, &o.view_scale_free,
                          &mc_trials, &mc_seed, &progress, &max_bytes, &o.solver,
                          &o.node_sigma, &o.node_sigma_sample))
        return NULL;
    if (progress != Py_None && !PyCallable_Check(progress)) {
        PyErr_SetString(PyExc_TypeError, "progress must be callable");
        return NULL;
    }
    progress_ctx pc = {progress, NULL, NULL, NULL};
    o.method = (sc_grid_method)method;
    sc_grid_data d;
    sc_grid_file_info info;
    if (grid_source(src, &d, &info, &path))
        return NULL;
    PyObject *warnings = PyList_New(0), *ret = NULL;
    sc_grid_solution s;
    sc_grid_mc mc;
    memset(&s, 0, sizeof s);
    memset(&mc, 0, sizeof mc);
    if (!warnings)
        goto done;
    o.warn = warn_collect; /* takes the GIL for each warning */
    o.warn_ctx = warnings;
    o.max_bytes = max_bytes > 0 ? max_bytes : sc_memory_available_bytes(); /* too large: refused, saying so */
    if (progress != Py_None)
        o.progress = progress_call, o.progress_ctx = &pc;
    sc_error err;
    sc_error_clear(&err);
    const char *pth = path ? PyBytes_AS_STRING(path) : NULL;
    sc_status st;
    Py_BEGIN_ALLOW_THREADS /* other Python threads run during the solve */
    st = sc_grid_calibrate(&d, path ? &info : NULL, pth, &o, &s, &err);
    if (st == SC_OK && mc_trials > 0)
        st = sc_grid_monte_carlo(&d, &o, &s, mc_trials, mc_seed, 0, &mc, &err);
    Py_END_ALLOW_THREADS
    if (pc.exc_type) { /* the progress function's exception, as it was raised */
        PyErr_Restore(pc.exc_type, pc.exc_value, pc.exc_tb);
        goto done;
    }
    if (st != SC_OK) {
        if (!err.file[0] && pth && (err.code == SC_E_INPUT || err.code == SC_E_UNSOLVABLE)) {
            snprintf(err.file, sizeof err.file, "%s", pth);
            if (!err.line)
                err.line = info.header_end_line;
        }
        raise_sc(&err);
        goto done;
    }
    ret = solution_to_dict(&d, &s, warnings);
    if (ret && set_item(ret, "budget", budget_to_dict(&d.plan, &s.budget)) != 0)
        Py_CLEAR(ret);
    if (ret && set_item(ret, "monte_carlo", mc_trials > 0 ? mc_to_dict(&d.plan, &mc)
                                                          : Py_NewRef(Py_None)) != 0)
        Py_CLEAR(ret);
done:
    sc_grid_mc_free(&mc);
    sc_grid_solution_free(&s);
    sc_grid_data_free(&d);
    sc_grid_file_info_free(&info);
    Py_XDECREF(path);
    Py_XDECREF(warnings);
    return ret;
}

/* grid_standard_plan(name, n, pitch_mm, ox, oy, nx, ny) -> plan dict */
static PyObject *py_grid_standard_plan(PyObject *self, PyObject *args)
{
    (void)self;
    const char *name;
    int n, nx, ny;
    double pitch, ox, oy;
    if (!PyArg_ParseTuple(args, "sidddii", &name, &n, &pitch, &ox, &oy, &nx, &ny))
        return NULL;
    sc_grid_plan p;
    sc_error err;
    sc_error_clear(&err);
    sc_status st;
    if (!strcmp(name, "ye"))
        st = sc_grid_plan_ye(n, pitch, ox, oy, &p, &err);
    else if (!strcmp(name, "double-shift"))
        st = sc_grid_plan_double_shift(n, pitch, ox, oy, &p, &err);
    else if (!strcmp(name, "stitch"))
        st = sc_grid_plan_stitch(n, nx, ny, pitch, ox, oy, &p, &err);
    else
        return PyErr_Format(sc_py_error, "plan must be 'ye', 'double-shift' or 'stitch', not '%s'", name);
    if (st != SC_OK)
        return raise_sc(&err);
    PyObject *r = plan_to_dict(&p);
    sc_grid_plan_free(&p);
    return r;
}

/* grid_simulate(plan dict, params dict) -> (measurement dict, truth dict) */
static PyObject *py_grid_simulate(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *pd, *params;
    if (!PyArg_ParseTuple(args, "OO!", &pd, &PyDict_Type, &params))
        return NULL;
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    if (plan_from_dict(pd, &d.plan))
        return NULL;
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    struct { const char *key; double *dst; } keys[] = {
        {"sigma_g_um", &sp.sigma_g_um}, {"rho", &sp.rho}, {"O", &sp.O}, {"R", &sp.R},
        {"sigma_a_um", &sp.sigma_a_um}, {"sigma_t_um", &sp.sigma_t_um},
        {"sigma_theta_urad", &sp.sigma_theta_urad}, {"sigma_r_um", &sp.sigma_r_um},
        {"dt_s", &sp.dt_s}, {"drift_vx_um_s", &sp.drift_vx_um_s},
        {"drift_vy_um_s", &sp.drift_vy_um_s}};
    const sc_grid_plan *p = &d.plan;
    long ns = sc_grid_stage_nodes(p), nm = (long)p->n * p->n, nv = p->n_views;
    sc_error err;
    sc_error_clear(&err);
    PyObject *ret = NULL;
    double *buf = NULL, *work = NULL;
    for (size_t k = 0; k < sizeof keys / sizeof keys[0]; ++k) {
        PyObject *v = PyDict_GetItemString(params, keys[k].key);
        if (v && opt_double(v, keys[k].dst))
            goto done;
    }
    PyObject *vs = PyDict_GetItemString(params, "seed");
    if (vs && ((sp.seed = PyLong_AsUnsignedLongLong(vs)), PyErr_Occurred()))
        goto done;
    if (sc_grid_data_alloc(&d, &err) != SC_OK ||
        (sp.dt_s > 0 && sc_grid_data_alloc_extra(&d, 0, 1, &err) != SC_OK)) {
        raise_sc(&err);
        goto done;
    }
    buf = malloc((2 * (size_t)ns + 2 * (size_t)nm + 3 * (size_t)nv) * sizeof(double));
    work = malloc(sc_grid_sim_work_doubles_plan(p) * sizeof(double) + 1);
    if (!buf || !work) {
        PyErr_NoMemory();
        goto done;
    }
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    t.gx_um = buf, t.gy_um = buf + ns, t.ax_um = buf + 2 * ns, t.ay_um = buf + 2 * ns + nm;
    t.tx_um = buf + 2 * ns + 2 * nm, t.ty_um = t.tx_um + nv, t.theta_urad = t.ty_um + nv;
    sc_status st;
    Py_BEGIN_ALLOW_THREADS
    st = sc_grid_sim_run(p, &sp, &t, &d, work, &err);
    Py_END_ALLOW_THREADS
    if (st != SC_OK) {
        raise_sc(&err);
        goto done;
    }
    npy_intp sg[2] = {sc_grid_stage_ny(p), sc_grid_stage_nx(p)}, sa[2] = {p->n, p->n};
    PyObject *meas = data_to_dict(&d);
    PyObject *truth = meas ? Py_BuildValue(
        "{s:N,s:N,s:N,s:N,s:d,s:d,s:d,s:d,s:N,s:N,s:N}", "gx_um", arr_from(t.gx_um, 2, sg), "gy_um",
        arr_from(t.gy_um, 2, sg), "ax_um", arr_from(t.ax_um, 2, sa), "ay_um",
        arr_from(t.ay_um, 2, sa), "O", t.O, "R", t.R, "O_urad", t.O * 1e6, "R_ppm", t.R * 1e6,
        "tx_um", per_view(t.tx_um, p->n_views),
        "ty_um", per_view(t.ty_um, p->n_views), "theta_urad", per_view(t.theta_urad, p->n_views))
                            : NULL;
    if (meas && truth)
        ret = Py_BuildValue("(NN)", meas, truth);
    else {
        Py_XDECREF(meas);
        Py_XDECREF(truth);
    }
done:
    free(buf);
    free(work);
    sc_grid_data_free(&d);
    return ret;
}

/* ---- tables ---- */

/* lut_build(path, gx_um, gy_um, x0_mm, y0_mm, px_mm, py_mm, profiles, method, sigma_um, created)
 * gx/gy: (NY, NX) float64; profiles: a sequence of (axis, dir, start_mm, step_mm, err_um array)
 * with axis/dir 0 x, 1 y, 2 z. Encoded (automatic int16/int32) and written atomically. */
static PyObject *py_lut_build(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *pathobj, *ogx, *ogy, *oprof;
    double x0, y0, px, py, sigma;
    const char *method;
    long long created;
    if (!PyArg_ParseTuple(args, "O&OOddddOsdL", PyUnicode_FSConverter, &pathobj, &ogx, &ogy, &x0, &y0,
                          &px, &py, &oprof, &method, &sigma, &created))
        return NULL;
    sc_lut *lut = malloc(sizeof *lut);
    PyArrayObject *gx = NULL, *gy = NULL;
    PyObject *ret = NULL, *seq = NULL;
    if (!lut) {
        PyErr_NoMemory();
        goto done;
    }
    sc_lut_init(lut);
    gx = (PyArrayObject *)PyArray_FROMANY(ogx, NPY_DOUBLE, 2, 2, NPY_ARRAY_IN_ARRAY);
    gy = gx ? (PyArrayObject *)PyArray_FROMANY(ogy, NPY_DOUBLE, 2, 2, NPY_ARRAY_IN_ARRAY) : NULL;
    if (!gy)
        goto done;
    npy_intp ny = PyArray_DIM(gx, 0), nx = PyArray_DIM(gx, 1);
    if (PyArray_DIM(gy, 0) != ny || PyArray_DIM(gy, 1) != nx || nx < 2 || ny < 2 ||
        nx > SC_LUT_MAX_NX || ny > SC_LUT_MAX_NY) {
        PyErr_Format(sc_py_error, "gx_um and gy_um must have one shape (NY, NX), 2..%d x 2..%d nodes",
                     SC_LUT_MAX_NY, SC_LUT_MAX_NX);
        goto done;
    }
    lut->nx = (int)nx, lut->ny = (int)ny;
    lut->x0_mm = x0, lut->y0_mm = y0, lut->px_mm = px, lut->py_mm = py;
    memcpy(lut->gx_um, PyArray_DATA(gx), (size_t)(nx * ny) * sizeof(double));
    memcpy(lut->gy_um, PyArray_DATA(gy), (size_t)(nx * ny) * sizeof(double));
    if (!(seq = PySequence_Fast(oprof, "profiles must be a sequence")))
        goto done;
    if (PySequence_Fast_GET_SIZE(seq) > SC_LUT_MAX_PROFILES) {
        PyErr_Format(sc_py_error, "at most %d profiles", SC_LUT_MAX_PROFILES);
        goto done;
    }
    for (Py_ssize_t k = 0; k < PySequence_Fast_GET_SIZE(seq); ++k) {
        sc_lut_profile *pr = &lut->profile[k];
        PyObject *vals;
        if (!PyArg_ParseTuple(PySequence_Fast_GET_ITEM(seq, k), "iiddO", &pr->axis, &pr->dir,
                              &pr->start_mm, &pr->step_mm, &vals))
            goto done;
        PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(vals, NPY_DOUBLE, 1, 1, NPY_ARRAY_IN_ARRAY);
        if (!a)
            goto done;
        npy_intp n = PyArray_DIM(a, 0);
        if (n < 2 || n > SC_LUT_MAX_PROFILE_POINTS) {
            Py_DECREF(a);
            PyErr_Format(sc_py_error, "profile %zd: 2..%d points, not %zd", k + 1,
                         SC_LUT_MAX_PROFILE_POINTS, (Py_ssize_t)n);
            goto done;
        }
        pr->n = (int)n;
        memcpy(pr->err_um, PyArray_DATA(a), (size_t)n * sizeof(double));
        Py_DECREF(a);
        lut->n_profiles = (int)k + 1;
    }
    snprintf(lut->prov.method, sizeof lut->prov.method, "%s", method);
    lut->prov.sigma_um = sigma;
    lut->prov.created_unix_s = created;
    sc_error err;
    sc_error_clear(&err);
    if (sc_lut_write_file(PyBytes_AS_STRING(pathobj), lut, SC_LUT_ENC_AUTO, &err) != SC_OK)
        raise_sc(&err);
    else
        ret = Py_NewRef(Py_None);
done:
    Py_XDECREF(seq);
    Py_XDECREF(gx);
    Py_XDECREF(gy);
    Py_DECREF(pathobj);
    free(lut);
    return ret;
}

/* ---- Table: a loaded correction table ---- */

typedef struct {
    PyObject_HEAD
    sc_corr_table *t; /* about 200 KB: allocated once at load */
} TableObject;

static void Table_dealloc(TableObject *self)
{
    free(self->t);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Table_init(TableObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", NULL};
    PyObject *pathobj = NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&", kwlist, PyUnicode_FSConverter, &pathobj))
        return -1;
    if (!self->t && !(self->t = malloc(sizeof *self->t))) {
        Py_DECREF(pathobj);
        PyErr_NoMemory();
        return -1;
    }
    sc_error err;
    sc_error_clear(&err);
    sc_status st = sc_lut_load_corr_file(PyBytes_AS_STRING(pathobj), self->t, &err);
    Py_DECREF(pathobj);
    if (st != SC_OK) {
        raise_sc(&err);
        return -1;
    }
    return 0;
}

/* A writable C-contiguous 1-D array of n elements of the given type, or NULL with an exception. */
static PyArrayObject *out_vec(PyObject *o, npy_intp n, int typenum, const char *what)
{
    if (!PyArray_Check(o) || PyArray_TYPE((PyArrayObject *)o) != typenum ||
        PyArray_NDIM((PyArrayObject *)o) != 1 || PyArray_DIM((PyArrayObject *)o, 0) != n ||
        !PyArray_ISCARRAY((PyArrayObject *)o)) {
        PyErr_Format(PyExc_ValueError, "%s must be a writable C-contiguous 1-D array of %zd %s", what,
                     (Py_ssize_t)n, typenum == NPY_DOUBLE ? "float64" : "uint32");
        return NULL;
    }
    return (PyArrayObject *)o;
}

/* The core reads x and y of its input as one 16-byte pair on x86-64: write them as one too, or
 * every point pays a store-forwarding stall (two 8-byte stores, one 16-byte load: 24 instead of
 * 11 ns per point, measured). */
#if defined(__GNUC__) && defined(__SSE2__)
typedef double xy_pair __attribute__((vector_size(16), may_alias));
#define STORE_XY(in, x, y) (*(xy_pair *)(in) = (xy_pair){(x), (y)})
#else
#define STORE_XY(in, x, y) ((in)[0] = (x), (in)[1] = (y))
#endif

/* apply(x, y, z, mode, x_out, y_out, z_out, status) — x, y: C-contiguous float64 arrays of one
 * length (mm), z likewise or None (0); mode 0 measure, 1 position, 2 measure-exact; the outputs are the caller's
 * arrays of that length (float64; z_out may be None; status uint32), filled in place: no
 * allocation, so a caller that reuses them pays no page faults. */
static PyObject *Table_apply(TableObject *self, PyObject *args)
{
    PyObject *xo, *yo, *zo, *oxo, *oyo, *ozo, *osto;
    int mode;
    if (!PyArg_ParseTuple(args, "OOOiOOOO", &xo, &yo, &zo, &mode, &oxo, &oyo, &ozo, &osto))
        return NULL;
    if (!self->t || !self->t->loaded) {
        PyErr_SetString(sc_py_error, "table not loaded");
        return NULL;
    }
    if (mode != SC_CORR_MEASURE && mode != SC_CORR_POSITION && mode != SC_CORR_MEASURE_EXACT) {
        PyErr_SetString(sc_py_error, "mode must be measure, position or measure-exact");
        return NULL;
    }
    const int req = NPY_ARRAY_IN_ARRAY;
    PyArrayObject *x = (PyArrayObject *)PyArray_FROMANY(xo, NPY_DOUBLE, 1, 1, req);
    PyArrayObject *y = x ? (PyArrayObject *)PyArray_FROMANY(yo, NPY_DOUBLE, 1, 1, req) : NULL;
    PyArrayObject *z = NULL;
    PyObject *ret = NULL;
    if (!y)
        goto done;
    if (zo != Py_None && !(z = (PyArrayObject *)PyArray_FROMANY(zo, NPY_DOUBLE, 1, 1, req)))
        goto done;
    npy_intp n = PyArray_DIM(x, 0);
    if (PyArray_DIM(y, 0) != n || (z && PyArray_DIM(z, 0) != n)) {
        PyErr_SetString(PyExc_ValueError, "x, y and z must have one length");
        goto done;
    }
    PyArrayObject *ox = out_vec(oxo, n, NPY_DOUBLE, "x_out"), *oy = ox ? out_vec(oyo, n, NPY_DOUBLE, "y_out") : NULL;
    PyArrayObject *oz = NULL, *ost = oy ? out_vec(osto, n, NPY_UINT32, "status") : NULL;
    if (!ost || (ozo != Py_None && !(oz = out_vec(ozo, n, NPY_DOUBLE, "z_out"))))
        goto done;
    {
        const double *px = PyArray_DATA(x), *py = PyArray_DATA(y), *pz = z ? PyArray_DATA(z) : NULL;
        double *qx = PyArray_DATA(ox), *qy = PyArray_DATA(oy), *qz = oz ? PyArray_DATA(oz) : NULL;
        npy_uint32 *qs = PyArray_DATA(ost);
        const sc_corr_table *t = self->t;
        Py_BEGIN_ALLOW_THREADS
        _Alignas(16) double in[3];
        double out[3];
        for (npy_intp k = 0; k < n; ++k) {
            STORE_XY(in, px[k], py[k]);
            in[2] = pz ? pz[k] : 0.0;
            qs[k] = sc_corr_apply(t, (sc_corr_mode)mode, in, out);
            qx[k] = out[0];
            qy[k] = out[1];
            if (qz)
                qz[k] = out[2];
        }
        Py_END_ALLOW_THREADS
    }
    ret = Py_NewRef(Py_None);
done:
    Py_XDECREF(x);
    Py_XDECREF(y);
    Py_XDECREF(z);
    return ret;
}

/* info() — the table's grid and profiles as a dict. */
static PyObject *Table_info(TableObject *self, PyObject *unused)
{
    (void)unused;
    const sc_corr_table *t = self->t;
    if (!t || !t->loaded) {
        PyErr_SetString(sc_py_error, "table not loaded");
        return NULL;
    }
    PyObject *profiles = PyList_New(0);
    if (!profiles)
        return NULL;
    static const char *axes = "xyz";
    for (int k = 0; k < t->n_profiles; ++k) {
        const sc_corr_profile *p = &t->profile[k];
        PyObject *d = Py_BuildValue("{s:C,s:C,s:i,s:d,s:d}", "axis", axes[p->axis], "dir",
                                    axes[p->dir], "n", (int)p->n, "start_mm", p->start_mm,
                                    "step_mm", p->step_mm);
        if (!d || PyList_Append(profiles, d) < 0) {
            Py_XDECREF(d);
            Py_DECREF(profiles);
            return NULL;
        }
        Py_DECREF(d);
    }
    return Py_BuildValue("{s:i,s:i,s:d,s:d,s:d,s:d,s:N}", "nx", (int)t->nx, "ny", (int)t->ny,
                         "x0_mm", t->x0_mm, "y0_mm", t->y0_mm, "px_mm", t->px_mm, "py_mm",
                         t->py_mm, "profiles", profiles);
}

static PyMethodDef Table_methods[] = {
    {"apply", (PyCFunction)Table_apply, METH_VARARGS,
     "apply(x, y, z, mode, x_out, y_out, z_out, status): 1-D arrays in mm, outputs filled in place."},
    {"info", (PyCFunction)Table_info, METH_NOARGS, "info() -> dict: grid size, node (0,0), pitches, profiles."},
    {NULL, NULL, 0, NULL}};

static PyTypeObject TableType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "selfcal._native.Table",
    .tp_basicsize = sizeof(TableObject),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "A correction table loaded into the correction core (read-only once loaded).",
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)Table_init,
    .tp_dealloc = (destructor)Table_dealloc,
    .tp_methods = Table_methods,
};

/* ---- verification of a compensated machine (selfcal/verify.h) ---- */

/* verify(measurement, table, artifact, tolerance_um, rule, u_verify_um, sigma_r_um, u_plate_um,
 * raw) -> dict; NaN for the numbers not given, rule 0 simple, 1 guarded. */
static PyObject *py_verify(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *pm = NULL, *pt = NULL, *pa = NULL;
    sc_verify_opts o;
    sc_verify_opts_init(&o);
    int rule = 0, raw = 0;
    if (!PyArg_ParseTuple(args, "O&O&O&didddp", PyUnicode_FSConverter, &pm, PyUnicode_FSConverter,
                          &pt, PyUnicode_FSConverter, &pa, &o.tolerance_um, &rule, &o.u_verify_um,
                          &o.sigma_r_um, &o.u_plate_um, &raw)) {
        Py_XDECREF(pm);
        Py_XDECREF(pt);
        Py_XDECREF(pa);
        return NULL;
    }
    o.measurement = PyBytes_AS_STRING(pm);
    o.table = PyBytes_AS_STRING(pt);
    o.artifact = PyBytes_AS_STRING(pa);
    o.rule = rule ? SC_VERIFY_RULE_GUARDED : SC_VERIFY_RULE_SIMPLE;
    o.raw = raw;
    sc_verify_result r;
    sc_error err;
    sc_error_clear(&err);
    sc_status st;
    Py_BEGIN_ALLOW_THREADS
    st = sc_verify_run(&o, &r, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(pm);
    Py_DECREF(pt);
    Py_DECREF(pa);
    PyObject *ret = NULL;
    if (st != SC_OK)
        raise_sc(&err);
    else {
        static const char *src[3] = {"given", "stated", "residuals"};
        const sc_verify_stats *b = &r.st_before, *a = &r.st_after;
        const sc_verify_u *u = &r.u;
        ret = Py_BuildValue(
            "{s:s,s:s,s:d,s:l,s:d,s:d,s:d,s:d,s:(dd),s:d,s:d,s:s,s:d,s:O,s:d,s:d,s:d,s:O,s:l,s:l}",
            "verdict", sc_verify_verdict_name(r.verdict), "decision_rule",
            sc_verify_rule_name(r.rule), "tolerance_um", o.tolerance_um, "marks", a->count,
            "before_rms_um", b->rms, "before_max_um", b->max, "after_rms_um", a->rms,
            "after_max_um", a->max, "after_max_at_mm", a->max_x_mm, a->max_y_mm, "U_um", u->U_um,
            "sigma_um", u->sigma_um, "sigma_source", u->given ? "none" : src[u->sigma_source],
            "u_plate_um", u->u_plate_um, "u_plate_given", u->u_plate_given ? Py_True : Py_False,
            "quant_um", u->quant_um, "u_um", u->u_um, "k", u->k,
            "U_given", u->given ? Py_True : Py_False, "n_unmeasured", r.n_unmeasured,
            "n_unseen", r.n_unseen);
    }
    sc_verify_result_free(&r);
    return ret;
}

/* ---- module ---- */

static PyObject *py_version(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    return PyUnicode_FromString(sc_version());
}

static PyMethodDef module_methods[] = {
    {"version", py_version, METH_NOARGS, "version() -> the libselfcal version string."},
    {"lut_build", py_lut_build, METH_VARARGS,
     "lut_build(path, gx, gy, x0, y0, px, py, profiles, method, sigma_um, created): write a table."},
    {"grid_read", py_grid_read, METH_VARARGS, "grid_read(path) -> measurement dict."},
    {"grid_write", py_grid_write, METH_VARARGS, "grid_write(path, measurement dict)."},
    {"grid_check", py_grid_check, METH_VARARGS,
     "grid_check(plan or measurement dict): checked as a calibration would, nothing solved."},
    {"grid_plan", py_grid_plan, METH_VARARGS, "grid_plan(path, plan or measurement) -> analysis dict."},
    {"grid_calibrate", py_grid_calibrate, METH_VARARGS,
     "grid_calibrate(src, method, sigma_r_um, drift, reject_outliers, covariance, outlier_alpha, "
     "outlier_alpha_each, estimate_view_noise, view_scale_free, mc_trials, mc_seed[, progress, "
     "max_bytes, solver, node_sigma, node_sigma_sample]) -> dict."},
    {"grid_standard_plan", py_grid_standard_plan, METH_VARARGS,
     "grid_standard_plan(name, n, pitch_mm, ox, oy, nx, ny) -> plan dict."},
    {"grid_simulate", py_grid_simulate, METH_VARARGS, "grid_simulate(plan, params) -> (measurement, truth)."},
    {"verify", py_verify, METH_VARARGS,
     "verify(measurement, table, artifact, tolerance_um, rule, u_verify_um, sigma_r_um, "
     "u_plate_um, raw) -> dict."},
    {"profile_read", py_profile_read, METH_VARARGS, "profile_read(path) -> measurement dict."},
    {"profile_write", py_profile_write, METH_VARARGS, "profile_write(path, measurement dict)."},
    {"profile_check", py_profile_check, METH_VARARGS, "profile_check(measurement dict)."},
    {"profile_calibrate", py_profile_calibrate, METH_VARARGS,
     "profile_calibrate(path or dict, method (0 dft, 1 lsq), sigma_disp_um, sigma_angle_urad, mc, seed) -> dict."},
    {"profile_simulate", py_profile_simulate, METH_VARARGS,
     "profile_simulate(params, f_um, amp_um, harmonics, dabam) -> (measurement, f_um, ey_um)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module_def = {PyModuleDef_HEAD_INIT, "selfcal._native",
                                        "libselfcal bindings (use the selfcal package).", -1,
                                        module_methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__native(void)
{
    import_array();
    if (PyType_Ready(&TableType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&module_def);
    if (!m)
        return NULL;
    /* the exceptions are Python classes (selfcal/_errors.py): kept for the module's life */
    PyObject *errors = PyImport_ImportModule("selfcal._errors");
    if (!errors) {
        Py_DECREF(m);
        return NULL;
    }
    struct { const char *name; PyObject **dst; } exc[] = {
        {"InputError", &sc_py_error},      {"UnsolvableError", &exc_unsolvable},
        {"FileError", &exc_file},          {"MissingFileError", &exc_missing},
        {"FilePermissionError", &exc_permission}, {"DirectoryError", &exc_directory},
        {"OutOfMemoryError", &exc_nomem},  {"InternalError", &exc_internal}};
    for (size_t k = 0; k < sizeof exc / sizeof exc[0]; ++k)
        if (!(*exc[k].dst = PyObject_GetAttrString(errors, exc[k].name))) {
            Py_DECREF(errors);
            Py_DECREF(m);
            return NULL;
        }
    Py_DECREF(errors);
    Py_INCREF(&TableType);
    if (PyModule_AddObject(m, "Table", (PyObject *)&TableType) < 0) {
        Py_DECREF(&TableType);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
