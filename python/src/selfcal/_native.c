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

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/correct.h"
#include "selfcal/error.h"
#include "selfcal/lut.h"
#include "selfcal/profile.h"
#include "selfcal/profile_calibrate.h"
#include "selfcal/profile_sim.h"
#include "selfcal/version.h"

static PyObject *sc_py_error; /* selfcal.Error, a ValueError */

/* Raise selfcal.Error with the library's one-line message ("file:line: reason"), the same text
 * the command line prints after "selfcal: ". Out-of-memory becomes MemoryError, I/O OSError. */
static PyObject *raise_sc(const sc_error *err)
{
    char buf[1024];
    sc_error_format(err, buf, sizeof buf);
    if (err->code == SC_E_NOMEM)
        PyErr_SetString(PyExc_MemoryError, buf);
    else if (err->code == SC_E_IO)
        PyErr_SetString(PyExc_OSError, buf);
    else
        PyErr_SetString(sc_py_error, buf);
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
        PyErr_SetString(PyExc_KeyError, "profile measurement lacks n, s_mm, d1, d2 or a sensor");
        return -1;
    }
    n = (int)PyLong_AsLong(on);
    d1 = (int)PyLong_AsLong(od1);
    d2 = (int)PyLong_AsLong(od2);
    s_mm = PyFloat_AsDouble(os);
    if (PyErr_Occurred() || opt_double(osd ? osd : Py_None, &sd) || opt_double(osa ? osa : Py_None, &sa))
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
    sc_status st = sc_profile_read(PyBytes_AS_STRING(path), d, &err);
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
        if (sc_profile_write(PyBytes_AS_STRING(pathobj), &d, &err) != SC_OK)
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
    if (opt_double(osd, &o.sigma_disp_um) || opt_double(osa, &o.sigma_angle_urad))
        return NULL;
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
        if (v) {
            *ikeys[k].dst = (int)PyLong_AsLong(v);
            if (PyErr_Occurred())
                return NULL;
        }
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

/* apply(x, y, z, mode) — x, y, z: C-contiguous float64 arrays of one length (mm); mode 0 measure,
 * 1 position. Returns (x_out, y_out, z_out, status) as new 1-D arrays. */
static PyObject *Table_apply(TableObject *self, PyObject *args)
{
    PyObject *xo, *yo, *zo;
    int mode;
    if (!PyArg_ParseTuple(args, "OOOi", &xo, &yo, &zo, &mode))
        return NULL;
    if (!self->t || !self->t->loaded) {
        PyErr_SetString(sc_py_error, "table not loaded");
        return NULL;
    }
    if (mode != SC_CORR_MEASURE && mode != SC_CORR_POSITION) {
        PyErr_SetString(sc_py_error, "mode must be measure or position");
        return NULL;
    }
    const int req = NPY_ARRAY_IN_ARRAY;
    PyArrayObject *x = (PyArrayObject *)PyArray_FROMANY(xo, NPY_DOUBLE, 1, 1, req);
    PyArrayObject *y = x ? (PyArrayObject *)PyArray_FROMANY(yo, NPY_DOUBLE, 1, 1, req) : NULL;
    PyArrayObject *z = y ? (PyArrayObject *)PyArray_FROMANY(zo, NPY_DOUBLE, 1, 1, req) : NULL;
    PyArrayObject *ox = NULL, *oy = NULL, *oz = NULL, *ost = NULL;
    PyObject *ret = NULL;
    if (!z)
        goto done;
    npy_intp n = PyArray_DIM(x, 0);
    if (PyArray_DIM(y, 0) != n || PyArray_DIM(z, 0) != n) {
        PyErr_SetString(PyExc_ValueError, "x, y and z must have one length");
        goto done;
    }
    ox = new_vec(n, NPY_DOUBLE);
    oy = new_vec(n, NPY_DOUBLE);
    oz = new_vec(n, NPY_DOUBLE);
    ost = new_vec(n, NPY_UINT32);
    if (!ox || !oy || !oz || !ost)
        goto done;
    {
        const double *px = PyArray_DATA(x), *py = PyArray_DATA(y), *pz = PyArray_DATA(z);
        double *qx = PyArray_DATA(ox), *qy = PyArray_DATA(oy), *qz = PyArray_DATA(oz);
        npy_uint32 *qs = PyArray_DATA(ost);
        const sc_corr_table *t = self->t;
        Py_BEGIN_ALLOW_THREADS
        for (npy_intp k = 0; k < n; ++k) {
            double in[3] = {px[k], py[k], pz[k]}, out[3];
            qs[k] = sc_corr_apply(t, (sc_corr_mode)mode, in, out);
            qx[k] = out[0];
            qy[k] = out[1];
            qz[k] = out[2];
        }
        Py_END_ALLOW_THREADS
    }
    ret = Py_BuildValue("OOOO", ox, oy, oz, ost);
done:
    Py_XDECREF(x);
    Py_XDECREF(y);
    Py_XDECREF(z);
    Py_XDECREF(ox);
    Py_XDECREF(oy);
    Py_XDECREF(oz);
    Py_XDECREF(ost);
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
     "apply(x, y, z, mode) -> (x, y, z, status): 1-D float64 arrays in mm; mode 0 measure, 1 position."},
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

/* ---- module ---- */

static PyObject *py_version(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    return PyUnicode_FromString(sc_version());
}

static PyMethodDef module_methods[] = {
    {"version", py_version, METH_NOARGS, "version() -> the libselfcal version string."},
    {"profile_read", py_profile_read, METH_VARARGS, "profile_read(path) -> measurement dict."},
    {"profile_write", py_profile_write, METH_VARARGS, "profile_write(path, measurement dict)."},
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
    sc_py_error = PyErr_NewExceptionWithDoc(
        "selfcal.Error",
        "Bad input or an unsolvable problem; the message is the library's one line "
        "(file:line: reason), as the command line prints it.",
        PyExc_ValueError, NULL);
    if (!sc_py_error || PyModule_AddObject(m, "Error", sc_py_error) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    Py_INCREF(sc_py_error); /* the module's reference was stolen; keep ours */
    Py_INCREF(&TableType);
    if (PyModule_AddObject(m, "Table", (PyObject *)&TableType) < 0) {
        Py_DECREF(&TableType);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
