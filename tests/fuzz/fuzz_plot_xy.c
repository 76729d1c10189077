/* tests/fuzz/fuzz_plot_xy.c — libFuzzer target: `selfcal plot xy` (tools/selfcal/cmd_plot_xy.c),
 * the CLI's own CSV reader (a header naming the columns, then numbers or empty fields) and the
 * chart drawn from it (tools/selfcal/svg.c), called as the command is, with its output written
 * through the atomic-file module into a private directory.
 * Input: one control byte (bit 0 --logx, bit 1 --logy, bit 2 --x taken from the second column's
 * name "b", bit 3 --y "c"), then the CSV.
 * Checks beyond "no memory error, no undefined behaviour, no hang": exit 0 or 2 (bad input, one
 * line naming the file) or 1 for a failed write only; on exit 0 a complete SVG document with no
 * NaN or infinity in it (a chart of the finite values only); on failure no output file. */
#include <math.h>
#include <stdarg.h>
#include <sys/stat.h>

#include "cli.h"
#include "fuzz_reader_check.h"

static int g_reports; /* lines the command printed */
static sc_status g_code;

int cli_report(const sc_error *err)
{
    ++g_reports;
    g_code = err->code;
    FUZZ_CHECK(err->msg[0] != '\0' && strchr(err->msg, '\n') == NULL);
    return (err->code == SC_E_INPUT || err->code == SC_E_UNSOLVABLE) ? CLI_BAD_INPUT : CLI_FAIL;
}

int cli_usage_error(const char *cmd, const char *fmt, ...)
{
    (void)cmd, (void)fmt;
    ++g_reports;
    g_code = SC_E_INPUT;
    return CLI_BAD_INPUT;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    uint8_t c = data[0];
    char in[320], out[320];
    snprintf(in, sizeof in, "%s", fuzz_path(data + 1, size - 1));
    snprintf(out, sizeof out, "%s/chart.svg", fuzz_dir());
    unlink(out);
    char *argv[12];
    int argc = 0;
    argv[argc++] = "xy";
    argv[argc++] = in;
    argv[argc++] = "-o";
    argv[argc++] = out;
    if (c & 1)
        argv[argc++] = "--logx";
    if (c & 2)
        argv[argc++] = "--logy";
    if (c & 4) {
        argv[argc++] = "--x";
        argv[argc++] = "b";
    }
    if (c & 8) {
        argv[argc++] = "--y";
        argv[argc++] = "c";
    }
    g_reports = 0;
    int rc = cmd_plot_xy(argc, argv);
    struct stat sb;
    int exists = stat(out, &sb) == 0;
    if (rc != CLI_OK) {
        FUZZ_CHECK(rc == CLI_BAD_INPUT || (rc == CLI_FAIL && g_code != SC_E_INPUT));
        FUZZ_CHECK(g_reports == 1 && !exists);
        return 0;
    }
    FUZZ_CHECK(g_reports == 0 && exists);
    FILE *f = fopen(out, "rb");
    FUZZ_CHECK(f != NULL);
    static char svg[1 << 22];
    size_t len = fread(svg, 1, sizeof svg - 1, f);
    fclose(f);
    svg[len] = '\0';
    FUZZ_CHECK(len > 0 && len < sizeof svg - 1);
    FUZZ_CHECK(strncmp(svg, "<svg", 4) == 0 || strncmp(svg, "<?xml", 5) == 0);
    FUZZ_CHECK(strstr(svg, "</svg>") != NULL);
    /* numbers in the drawing: no nan, no inf (column names from the CSV are escaped text, so
     * look only inside attribute values of the drawing elements) */
    for (const char *p = svg; (p = strchr(p, '"')) != NULL;) {
        const char *q = strchr(p + 1, '"');
        FUZZ_CHECK(q != NULL);
        size_t n = (size_t)(q - p - 1);
        char val[64];
        if (n < sizeof val) {
            memcpy(val, p + 1, n);
            val[n] = '\0';
            if (strspn(val, "0123456789.-+eE, naif") == n && (strstr(val, "nan") || strstr(val, "inf"))) {
                fprintf(stderr, "non-finite number in the SVG: \"%s\"\n", val);
                FUZZ_CHECK(0);
            }
        }
        p = q + 1;
    }
    return 0;
}
