/* runtime/engine.c — the table slots, reload and the nm <-> mm correction of selfcald.
 * A reload runs inside the loop, so it must not wait: only a regular file of at most
 * SC_ENGINE_MAX_TABLE_BYTES is read (a FIFO, socket or device at the path is refused at once).
 * A file system that hangs a read of a regular file would still stall it. */
#include "engine.h"

#include "selfcal/csv.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Two slots: the one in use and the spare that a reload fills. */
static sc_corr_table g_slot[2];
static unsigned char g_filebuf[SC_ENGINE_MAX_TABLE_BYTES + 1];

void sc_engine_init(sc_engine *e, sc_corr_mode mode)
{
    memset(e, 0, sizeof *e);
    e->mode = mode;
}

static sc_status read_file(const char *path, size_t *len, sc_error *err)
{
    /* O_NONBLOCK: opening a FIFO (or a device) at the table path must not wait for a writer;
     * anything but a regular file is then refused before a byte is read, and the read is
     * bounded by the buffer. */
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
    if (fd < 0)
        return sc_error_set(err, sc_open_failure_status(errno), path, 0, "cannot open: %s",
                            strerror(errno));
    sc_status st = SC_OK;
    struct stat sb;
    size_t n = 0;
    if (fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        st = sc_error_set(err, SC_E_INPUT, path, 0, "not a regular file");
    } else if (sb.st_size > (off_t)SC_ENGINE_MAX_TABLE_BYTES) {
        st = sc_error_set(err, SC_E_INPUT, path, 0, "larger than %u bytes, not a selfcal table",
                          (unsigned)SC_ENGINE_MAX_TABLE_BYTES);
    } else {
        for (;;) {
            ssize_t r = read(fd, g_filebuf + n, sizeof g_filebuf - n);
            if (r < 0 && errno == EINTR)
                continue;
            if (r < 0) {
                st = sc_error_set(err, SC_E_IO, path, 0, "read error: %s", strerror(errno));
                break;
            }
            if (r == 0)
                break;
            n += (size_t)r;
            if (n == sizeof g_filebuf) {
                st = sc_error_set(err, SC_E_INPUT, path, 0,
                                  "larger than %u bytes, not a selfcal table",
                                  (unsigned)SC_ENGINE_MAX_TABLE_BYTES);
                break;
            }
        }
    }
    close(fd);
    *len = n;
    return st;
}

/* The plausibility bounds of e against table t (just loaded from path). */
static sc_status check_bounds(const sc_engine *e, const sc_corr_table *t, const char *path,
                              sc_error *err)
{
    double corr_um, grad;
    sc_corr_bounds(t, &corr_um, &grad);
    if (e->max_correction_um > 0 && !(corr_um <= e->max_correction_um))
        return sc_error_set(err, SC_E_INPUT, path, 0,
                            "the table can command a correction of %.3f um, beyond "
                            "--max-correction-um %g",
                            corr_um, e->max_correction_um);
    if (e->max_gradient_um_per_mm > 0 && !(grad <= e->max_gradient_um_per_mm))
        return sc_error_set(err, SC_E_INPUT, path, 0,
                            "the table changes by %.3f um per mm between neighbouring nodes, "
                            "beyond --max-gradient-um-per-mm %g",
                            grad, e->max_gradient_um_per_mm);
    return SC_OK;
}

sc_status sc_engine_load_file(sc_engine *e, const char *path, sc_error *err)
{
    size_t len = 0;
    sc_corr_table *spare = (e->table == &g_slot[0]) ? &g_slot[1] : &g_slot[0];
    sc_status st = read_file(path, &len, err);
    if (st == SC_OK) {
        int code = sc_corr_load(spare, g_filebuf, len);
        if (code != SC_CORR_OK)
            st = sc_error_set(err, SC_E_INPUT, path, 0, "not a valid table: %s",
                              sc_corr_explain(g_filebuf, len));
        else
            st = check_bounds(e, spare, path, err);
    }
    if (st != SC_OK) {
        e->reload_failed++;
        e->status |= SC_ENGINE_ST_RELOAD_FAILED;
        return st;
    }
    e->reload_ok += e->table != NULL; /* the first load is not a reload */
    e->table = spare;
    e->status = (uint16_t)((e->status & ~SC_ENGINE_ST_RELOAD_FAILED) | SC_CORR_ST_LOADED);
    return SC_OK;
}

int32_t sc_engine_mm_to_nm(double v_mm, int *saturated)
{
    double v = v_mm * 1e6;
    if (!(v == v)) { /* NaN */
        *saturated = 1;
        return 0;
    }
    v = nearbyint(v); /* round half to even in the default mode: nearest nm */
    if (v > (double)INT32_MAX) {
        *saturated = 1;
        return INT32_MAX;
    }
    if (v < (double)INT32_MIN) {
        *saturated = 1;
        return INT32_MIN;
    }
    return (int32_t)v;
}

uint16_t sc_engine_correct(sc_engine *e, int32_t x_nm, int32_t y_nm, int32_t *out_x_nm,
                           int32_t *out_y_nm)
{
    const double in[3] = {(double)x_nm * 1e-6, (double)y_nm * 1e-6, 0.0};
    double out[3] = {in[0], in[1], in[2]};
    unsigned st = 0;
    if (e->table != NULL && e->table->loaded)
        st = sc_corr_apply(e->table, e->mode, in, out);
    int sat = 0;
    int32_t ox = sc_engine_mm_to_nm(out[0], &sat);
    int32_t oy = sc_engine_mm_to_nm(out[1], &sat);
    if (sat)
        st |= SC_CORR_ST_INVALID;
    st &= (SC_CORR_ST_LOADED | SC_CORR_ST_OUTSIDE | SC_CORR_ST_INVALID);
    if (e->table != NULL && e->table->loaded)
        st |= SC_CORR_ST_LOADED;
    e->status = (uint16_t)(st | (e->status & SC_ENGINE_ST_RELOAD_FAILED));
    e->corrections++;
    e->last_in_x_nm = x_nm;
    e->last_in_y_nm = y_nm;
    e->last_out_x_nm = ox;
    e->last_out_y_nm = oy;
    *out_x_nm = ox;
    *out_y_nm = oy;
    return e->status;
}
