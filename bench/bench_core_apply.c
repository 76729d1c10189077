/* bench_core_apply — nanoseconds per sc_corr_apply() on the host with a 25 x 25 map and two
 * 330-point profiles (goal: <= 10 ns), and the size of that table file.
 *   usage: bench_core_apply [calls]   (default 20 000 000 per mode, in 40 bursts; best burst;
 *   thread CPU time)
 * Inputs cycle through 4096 random positions (inside the grid, and a second set partly outside),
 * so that the branch predictor cannot learn one path. Build Release without sanitizers.
 *
 * Every call is a real call of the library function (its own translation unit in a static
 * library: no inlining across it) on a fresh input, and every output is consumed. Two figures:
 *  - throughput (independent calls, as when a stream of positions is corrected): the outputs are
 *    folded into an integer checksum held in a register, so the harness adds no chain of its own
 *    through memory (the earlier harness kept a double sum in memory across the call: a ~10-cycle
 *    store-to-load chain per call, which set a 3.4 ns floor of its own);
 *  - latency (each call's input depends on the previous call's output, as in a loop that waits
 *    for one correction before the next): the time from an input to its corrected output. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "selfcal/correct.h"
#include "selfcal/lut.h"
#include "selfcal/rng.h"

#define NPOS 4096

/* This thread's CPU time: on a shared machine, time spent preempted is not counted. */
static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static sc_corr_table table;

/* The loop and call overhead alone: a call of the same shape that only copies. */
__attribute__((noinline)) static unsigned copy_only(const sc_corr_table *t, sc_corr_mode mode,
                                                    const double in[3], double out[3])
{
    (void)t;
    (void)mode;
    out[0] = in[0];
    out[1] = in[1];
    out[2] = in[2];
    return 1u;
}
static double pos[NPOS][3];

/* The bits of a double, to fold outputs into an integer checksum. */
static inline uint64_t bits(double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    return u;
}

/* mode 0 measure, 1 position, 2 inverse (3 iterations), 3 copy_only; dependent: each input
 * depends on the previous output (latency) instead of independent calls (throughput). Returns ns
 * per call: the best of 40 bursts of calls/40 (short bursts, so that some run without
 * interference). */
static double time_mode(int mode, int dependent, long calls, double *sink)
{
    double best = 1e30;
    calls /= 40;
    for (int rep = 0; rep < 40; ++rep) {
        double out[3] = {0, 0, 0};
        uint64_t h = 0;
        unsigned st = 0;
        double t0 = now_s();
        for (long k = 0; k < calls; ++k) {
            const double *p = pos[k & (NPOS - 1)];
            double dep[3];
            if (dependent) {
                /* out - out is 0 for the finite outputs here, but the compiler cannot know it:
                 * the next input waits for this output. */
                const double zero = out[0] - out[0];
                dep[0] = p[0] + zero;
                dep[1] = p[1] + zero;
                dep[2] = p[2] + zero;
                p = dep;
            }
            if (mode == 3)
                st += copy_only(&table, SC_CORR_MEASURE, p, out);
            else if (mode == 2)
                st += sc_corr_apply_inverse(&table, p, out, 3);
            else
                st += sc_corr_apply(&table, (sc_corr_mode)mode, p, out);
            h += bits(out[0]) ^ bits(out[1]) ^ bits(out[2]);
        }
        double dt = now_s() - t0;
        *sink += (double)(h & 0xFFFF) + st;
        if (dt < best)
            best = dt;
    }
    return 1e9 * best / (double)calls;
}

int main(int argc, char **argv)
{
    long calls = argc > 1 ? atol(argv[1]) : 20000000L;
    if (calls < 1000)
        calls = 1000;
    sc_rng rng;
    sc_rng_seed(&rng, 1);
    sc_lut *lut = malloc(sizeof *lut);
    if (!lut)
        return 1;
    sc_lut_init(lut);
    lut->nx = lut->ny = 25;
    lut->x0_mm = lut->y0_mm = -12.0;
    lut->px_mm = lut->py_mm = 1.0;
    for (int k = 0; k < 625; ++k) {
        lut->gx_um[k] = sc_rng_normal(&rng);
        lut->gy_um[k] = sc_rng_normal(&rng);
    }
    lut->n_profiles = 2;
    for (int p = 0; p < 2; ++p) {
        lut->profile[p].axis = p;
        lut->profile[p].dir = p == 0 ? SC_CORR_AXIS_Y : SC_CORR_AXIS_Z;
        lut->profile[p].n = 330;
        lut->profile[p].start_mm = -165.0;
        lut->profile[p].step_mm = 1.0;
        for (int m = 0; m < 330; ++m)
            lut->profile[p].err_um[m] = 0.2 * sc_rng_normal(&rng);
    }
    lut->prov.n_sources = 3;
    snprintf(lut->prov.method, sizeof lut->prov.method, "bench");
    static uint8_t img[16384];
    size_t len16 = 0, len32 = 0;
    sc_error err;
    if (sc_lut_encode(lut, SC_LUT_ENC_INT32, img, sizeof img, &len32, &err) != SC_OK ||
        sc_lut_encode(lut, SC_LUT_ENC_INT16, img, sizeof img, &len16, &err) != SC_OK) {
        fprintf(stderr, "encode: %s\n", err.msg);
        return 1;
    }
    const double q16_nm = 1e3 * sc_lut_quantization_um(lut->grid_scale_pm);
    double t0 = now_s();
    int rc = 0;
    for (int k = 0; k < 1000; ++k)
        rc |= sc_corr_load(&table, img, len16);
    double load_us = (now_s() - t0) * 1e3;
    if (rc != SC_CORR_OK) {
        fprintf(stderr, "load: %s\n", sc_corr_strerror(rc));
        return 1;
    }
    double sink = 0;
    printf("correction core, 25 x 25 map + 2 profiles x 330 points, %ld calls per mode, best of 40 bursts, thread CPU time\n"
           "(ns/call: independent calls; latency: each input waits for the previous output)\n",
           calls);
    printf("%-36s %11s %11s\n", "case", "ns/call", "latency ns");
    for (int k = 0; k < NPOS; ++k) {
        pos[k][0] = -12.0 + 24.0 * sc_rng_uniform(&rng);
        pos[k][1] = -12.0 + 24.0 * sc_rng_uniform(&rng);
        pos[k][2] = 0.0;
    }
#define ROW(name, mode, n)                                                                        \
    printf("%-36s %11.2f %11.2f\n", name, time_mode(mode, 0, n, &sink), time_mode(mode, 1, n, &sink))
    ROW("loop + call overhead (copy only)", 3, calls);
    ROW("apply measure (inside)", 0, calls);
    ROW("apply position (inside)", 1, calls);
    ROW("apply_inverse, 3 iterations", 2, calls / 4);
    for (int k = 0; k < NPOS; ++k) {
        pos[k][0] = -20.0 + 40.0 * sc_rng_uniform(&rng);
        pos[k][1] = -20.0 + 40.0 * sc_rng_uniform(&rng);
    }
    ROW("apply measure (~64% outside)", 0, calls);
    /* The same map without its profiles: the grid's share. */
    lut->n_profiles = 0;
    size_t len0 = 0;
    if (sc_lut_encode(lut, SC_LUT_ENC_AUTO, img, sizeof img, &len0, &err) != SC_OK ||
        sc_corr_load(&table, img, len0) != SC_CORR_OK)
        return 1;
    ROW("apply measure, map only (no profile)", 0, calls);
    printf("\nsc_corr_load (validate + decode):  %.2f us per table\n", load_us);
    printf("table file size: %zu bytes (int16 codes, quantization <= %.3f nm), "
           "%zu bytes with int32 codes (<= 0.0005 nm); budget 8192\n",
           len16, q16_nm, len32);
    printf("sizeof(sc_corr_table) = %zu bytes (host capacity %d x %d, %d x %d profile points)\n",
           sizeof table, SC_CORR_MAX_NX, SC_CORR_MAX_NY, SC_CORR_MAX_PROFILES, SC_CORR_MAX_PROFILE_POINTS);
    if (sink == 42.0)
        printf("(sink)\n");
    free(lut);
    return 0;
}
