/* selfcal simulate profile — simulated two-scan straightness data (SPEC §2) plus the truth. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "selfcal/csv.h"
#include "selfcal/profile.h"
#include "selfcal/profile_sim.h"

static const char *USAGE =
    "usage: selfcal simulate profile --out IN.csv --truth T.csv [options]\n"
    "  --n N (330)  --s-mm S (1)  --d1 D1 (10)  --d2 D2 (11)\n"
    "  --profile random|FILE.dat (random; FILE.dat: a DABAM profile with its .txt metadata)\n"
    "  --amp-um A (1: RMS of a random profile)  --harmonics H (40)\n"
    "  --sigma-disp-um X (0.01)  --sigma-angle-urad Y (1)  [--noise-free] [--no-sigma-lines]\n"
    "  --ey-um A (0.5)  --ep-urad A (2)  --u1-um U (1.5)  --u2-um U (-0.7)  --u3-urad U (3)\n"
    "  --b0-um B (20)  --seed S (1)\n"
    "  Writes the selfcal-profile v1 data file and the truth n,x_mm,f_um,uf_um,ey_um (f and e_y\n"
    "  relative to their least-squares lines; uf empty; e_y empty where n >= N - d1).\n";

static int get_double(const char *opt, const char *s, double *out)
{
    if (sc_parse_double(s, out) != 0)
        return cli_usage_error("simulate profile", "%s: '%s' is not a number", opt, s);
    return 0;
}

static int get_int(const char *opt, const char *s, long lo, long hi, long *out)
{
    if (sc_parse_long(s, out) != 0 || *out < lo || *out > hi)
        return cli_usage_error("simulate profile", "%s: '%s' must be a whole number in %ld..%ld", opt,
                               s, lo, hi);
    return 0;
}

int cmd_simulate_profile(int argc, char **argv)
{
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    const char *out = NULL, *truth = NULL, *prof = "random";
    double amp = 1.0;
    long harmonics = 40;
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        int hv = i + 1 < argc;
        long v;
        int bad = 0;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(USAGE, stdout);
            return CLI_OK;
        } else if ((!strcmp(a, "--out") || !strcmp(a, "-o")) && hv)
            out = argv[++i];
        else if (!strcmp(a, "--truth") && hv)
            truth = argv[++i];
        else if (!strcmp(a, "--profile") && hv)
            prof = argv[++i];
        else if ((!strcmp(a, "--n") || !strcmp(a, "--N")) && hv) {
            bad = get_int(a, argv[++i], 3, 100000000, &v);
            p.n = (int)v;
        } else if (!strcmp(a, "--d1") && hv) {
            bad = get_int(a, argv[++i], 1, 100000000, &v);
            p.d1 = (int)v;
        } else if (!strcmp(a, "--d2") && hv) {
            bad = get_int(a, argv[++i], 1, 100000000, &v);
            p.d2 = (int)v;
        } else if (!strcmp(a, "--harmonics") && hv) {
            bad = get_int(a, argv[++i], 1, 100000, &harmonics);
        } else if (!strcmp(a, "--seed") && hv) {
            char *e;
            p.seed = strtoull(argv[++i], &e, 10);
            if (*e || !*argv[i])
                bad = cli_usage_error("simulate profile", "--seed: '%s' is not a whole number", argv[i]);
        } else if (!strcmp(a, "--s-mm") && hv)
            bad = get_double(a, argv[++i], &p.s_mm);
        else if (!strcmp(a, "--amp-um") && hv)
            bad = get_double(a, argv[++i], &amp);
        else if (!strcmp(a, "--sigma-disp-um") && hv)
            bad = get_double(a, argv[++i], &p.sigma_disp_um);
        else if (!strcmp(a, "--sigma-angle-urad") && hv)
            bad = get_double(a, argv[++i], &p.sigma_angle_urad);
        else if (!strcmp(a, "--ey-um") && hv)
            bad = get_double(a, argv[++i], &p.ey_amp_um);
        else if (!strcmp(a, "--ep-urad") && hv)
            bad = get_double(a, argv[++i], &p.ep_amp_urad);
        else if (!strcmp(a, "--u1-um") && hv)
            bad = get_double(a, argv[++i], &p.u1_um);
        else if (!strcmp(a, "--u2-um") && hv)
            bad = get_double(a, argv[++i], &p.u2_um);
        else if (!strcmp(a, "--u3-urad") && hv)
            bad = get_double(a, argv[++i], &p.u3_urad);
        else if (!strcmp(a, "--b0-um") && hv)
            bad = get_double(a, argv[++i], &p.b0_um);
        else if (!strcmp(a, "--noise-free"))
            p.sigma_disp_um = p.sigma_angle_urad = 0;
        else if (!strcmp(a, "--no-sigma-lines"))
            p.write_sigma = 0;
        else
            return cli_usage_error("simulate profile", "unknown option or missing value: %s (see --help)", a);
        if (bad)
            return CLI_BAD_INPUT;
    }
    if (!out || !truth) {
        return cli_usage_error("simulate profile", "--out and --truth are required (see --help)");
    }
    if (!(p.s_mm > 0))
        return cli_usage_error("simulate profile", "--s-mm must be positive");
    if (p.d1 >= p.n || p.d2 >= p.n)
        return cli_usage_error("simulate profile", "spacings d1 = %d, d2 = %d leave no sample for N = %d",
                               p.d1, p.d2, p.n);
    if (p.sigma_disp_um < 0 || p.sigma_angle_urad < 0 || amp < 0)
        return cli_usage_error("simulate profile", "noise levels and amplitudes must be non-negative");
    sc_error err;
    sc_error_clear(&err);
    const int n = p.n;
    double *f = malloc((size_t)n * sizeof(double)), *ey = malloc((size_t)n * sizeof(double));
    int rc = CLI_FAIL;
    sc_profile_data d;
    memset(&d, 0, sizeof d);
    if (!f || !ey) {
        sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto done;
    }
    char info[512] = "random smooth profile";
    if (!strcmp(prof, "random")) {
        sc_profile_sim_random_truth(&p, amp, (int)harmonics, f);
    } else if (sc_profile_load_dabam(prof, n, p.s_mm, f, info, sizeof info, &err) != SC_OK) {
        goto done;
    }
    if (sc_profile_simulate(&p, f, &d, ey, &err) != SC_OK)
        goto done;
    sc_profile_remove_line(n - p.d1, ey);
    /* both files are computed; write the data, then the truth (each atomically) */
    if (sc_profile_write(out, &d, &err) != SC_OK ||
        sc_profile_write_result(truth, n, p.s_mm, f, NULL, ey, n - p.d1, &err) != SC_OK)
        goto done;
    printf("%s\n", info);
    rc = CLI_OK;
done:
    if (rc != CLI_OK)
        rc = cli_report(&err);
    sc_profile_data_free(&d);
    free(f);
    free(ey);
    return rc;
}
