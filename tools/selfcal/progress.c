/* Progress of long grid solves on stderr (a terminal, or --progress) and the memory a command
 * may use (the machine's available memory; --max-memory is read in cli.c). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/csv.h"

double cli_memory_bytes(void)
{
    return sc_memory_available_bytes(); /* MemAvailable: what can be had without swapping */
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

void cli_progress_init(cli_progress *p, const char *cmd, int asked, double limit_bytes)
{
    memset(p, 0, sizeof *p);
    p->cmd = cmd;
    p->tty = isatty(STDERR_FILENO);
    p->on = asked || p->tty;
    p->limit_bytes = limit_bytes;
    p->t0 = now_s();
    p->work_t0 = -1;
}

/* "12.3 s", "4 min 05 s" */
static void fmt_time(char *b, size_t n, double s)
{
    if (s < 100)
        snprintf(b, n, "%.1f s", s);
    else
        snprintf(b, n, "%d min %02d s", (int)(s / 60), (int)fmod(s, 60));
}

void cli_progress_phase(cli_progress *p, const char *phase, double done, double total,
                        double peak_bytes)
{
    if (!p->on)
        return;
    double t = now_s(), el = t - p->t0;
    if (peak_bytes > 0 && !p->stated) { /* the memory, stated once, as soon as it is known */
        p->stated = 1;
        fprintf(stderr, "%sselfcal %s: peak memory about %.2f GiB (estimated from the plan) of "
                        "%.2f GiB allowed\n",
                p->tty && p->open ? "\n" : "", p->cmd, peak_bytes / 1073741824.0,
                p->limit_bytes / 1073741824.0);
        p->open = 0;
    }
    if (!strcmp(phase, "factor"))
        p->work_t0 = t; /* the factor starts: its rate times what is left */
    char left[64] = "";
    if (total > 0 && done > 0 && done < total && p->work_t0 >= 0 && t > p->work_t0) {
        char b[32];
        double rate = done / (t - p->work_t0);
        fmt_time(b, sizeof b, done >= total ? 0 : (total - done) / rate);
        snprintf(left, sizeof left, ", about %s left", b);
    }
    char b[32];
    fmt_time(b, sizeof b, el);
    if (p->tty) { /* one line, rewritten */
        fprintf(stderr, "\rselfcal %s: %-16s %5.1f %% of the work, %s%s\033[K", p->cmd, phase,
                total > 0 ? 100.0 * done / total : 0.0, b, left);
        p->open = 1;
    } else {
        fprintf(stderr, "selfcal %s: %s (%s%s)\n", p->cmd, phase, b, left);
    }
    fflush(stderr);
}

void cli_progress_lsq(void *ctx, const char *phase, double work_done, double work_total,
                      double peak_bytes)
{
    cli_progress_phase(ctx, phase, work_done, work_total, peak_bytes);
}

void cli_progress_end(cli_progress *p)
{
    if (p->on && p->tty && p->open)
        fputc('\n', stderr);
    p->open = 0;
}
