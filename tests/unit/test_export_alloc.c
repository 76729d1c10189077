/* Allocation-failure injection into the controller exporters (selfcal/export.h), as
 * test_alloc_fail does for the readers and solvers: each export is run failing its 1st
 * allocation, then its 2nd, and so on until a run needs no failed allocation. Every run that hit
 * a failure must return SC_E_NOMEM with a message (never SC_OK with a table silently left short,
 * never a crash) and free what it allocated (LeakSanitizer checks at exit in the sanitizer
 * build). The hook is the linker's --wrap (export_alloc.cmake): the library's malloc, calloc and
 * realloc in this executable only. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/export.h"
#include "selfcal/lut.h"

static long fail_at, counted;
static int injected;

static int fail_now(void)
{
    if (!fail_at || ++counted != fail_at)
        return 0;
    injected = 1;
    return 1;
}

void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t m);
void *__real_realloc(void *p, size_t n);
void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t n, size_t m);
void *__wrap_realloc(void *p, size_t n);

void *__wrap_malloc(size_t n) { return fail_now() ? NULL : __real_malloc(n); }
void *__wrap_calloc(size_t n, size_t m) { return fail_now() ? NULL : __real_calloc(n, m); }
void *__wrap_realloc(void *p, size_t n) { return fail_now() ? NULL : __real_realloc(p, n); }

/* One export, failing allocation k = 1, 2, ... until a run completes without a failure; returns
 * how many allocations it made. */
static long every_allocation(const char *name, const sc_lut *m, const sc_export_options *o)
{
    for (long k = 1;; ++k) {
        sc_export_report rep;
        sc_error err;
        sc_error_clear(&err);
        counted = 0;
        injected = 0;
        fail_at = k;
        sc_status st = sc_export_write(m, o, NULL, &rep, &err);
        fail_at = 0;
        if (!injected) {
            if (st != SC_OK)
                fail_msg("%s: status %d without an injected failure: %s", name, st, err.msg);
            return k - 1;
        }
        if (st != SC_E_NOMEM)
            fail_msg("%s: allocation %ld failed but the export returned %d (%s)", name, k, st,
                     st == SC_OK ? "the failure was skipped" : err.msg);
        if (!strstr(err.msg, "out of memory"))
            fail_msg("%s: allocation %ld: message '%s'", name, k, err.msg);
        if (k > 10000)
            fail_msg("%s: no end of allocations", name);
    }
}

static void test_every_format(void **state)
{
    (void)state;
    sc_lut *m = __real_malloc(sizeof *m);
    assert_non_null(m);
    sc_lut_init(m);
    m->nx = 9;
    m->ny = 7;
    m->x0_mm = -20.0;
    m->y0_mm = -15.0;
    m->px_mm = 5.0;
    m->py_mm = 5.0;
    for (int i = 0; i < m->ny; ++i)
        for (int j = 0; j < m->nx; ++j) {
            m->gx_um[i * m->nx + j] = 0.8 * sin(0.3 * j) + 0.02 * i * i + 1e-3 * i;
            m->gy_um[i * m->nx + j] = -0.6 * cos(0.2 * i) + 0.01 * j * j;
        }
    sc_lut_profile *p = &m->profile[0];
    p->axis = 0;
    p->dir = 2;
    p->n = 41;
    p->start_mm = -20.0;
    p->step_mm = 1.0;
    for (int k = 0; k < p->n; ++k)
        p->err_um[k] = 0.5 * sin(0.2 * k);
    m->n_profiles = 1;
    const char *names[] = {"beckhoff", "siemens-cec", "linuxcnc", "klipper", "marlin",
                           "reprap", "kmotion", "aerotech-a1", "powerpmac"};
    for (int f = SC_EXPORT_BECKHOFF; f <= SC_EXPORT_POWERPMAC; ++f) {
        sc_export_options o;
        sc_export_options_init(&o, (sc_export_format)f);
        long n = every_allocation(names[f], m, &o);
        assert_true(n >= 1); /* at least the text it writes */
        print_message("%s: %ld allocations, each failure reported\n", names[f], n);
    }
    /* the cross compensation list of a profile */
    sc_export_options o;
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    o.cross_profile = 0;
    assert_true(every_allocation("beckhoff cross", m, &o) >= 1);
    free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_format),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
