/* output_paths.c — a command's outputs checked against its inputs and each other before it runs.
 * Every command reads its inputs, then replaces its outputs atomically (a temporary file renamed
 * over the name): `--out IN.csv` would therefore succeed and destroy IN.csv, and two outputs on
 * one path would leave only the last. Outputs are the values of the options the command table
 * lists; inputs are every other argument that names an existing file (and the file of a
 * --profile AXIS:DIR:FILE[@OFFSET]). */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"

#define MAX_PATHS 64

typedef struct named_file {
    const char *arg;  /* as given */
    const char *opt;  /* the option it follows (outputs), or NULL */
    int exists;
    dev_t dev;
    ino_t ino;
} named_file;

static int is_output_option(const char *outputs, const char *a)
{
    size_t len = strlen(a);
    for (const char *p = outputs; p && *p;) {
        const char *end = strchr(p, ' ');
        size_t n = end ? (size_t)(end - p) : strlen(p);
        if (n == len && !strncmp(p, a, n))
            return 1;
        p = end ? end + 1 : p + n;
    }
    return 0;
}

/* A file an output can clash with an input on: a regular file, or a pipe (FIFO, /dev/stdin
 * from a pipe, a socket): not a device (/dev/null, a terminal) that is rightly both. */
static int clash_kind(const struct stat *st)
{
    return S_ISREG(st->st_mode) || S_ISFIFO(st->st_mode) || S_ISSOCK(st->st_mode);
}

static void identify(named_file *f)
{
    struct stat st;
    f->exists = stat(f->arg, &st) == 0 && clash_kind(&st);
    f->dev = f->exists ? st.st_dev : 0;
    f->ino = f->exists ? st.st_ino : 0;
}

/* The same file: the same inode where both exist, else the same path once the folder is
 * resolved (a new file named two ways). */
static int same_file(const named_file *a, const named_file *b)
{
    if (a->exists || b->exists)
        return a->exists && b->exists && a->dev == b->dev && a->ino == b->ino;
    if (!strcmp(a->arg, b->arg))
        return 1;
    char da[PATH_MAX], db[PATH_MAX], ra[PATH_MAX], rb[PATH_MAX];
    const char *ba = strrchr(a->arg, '/'), *bb = strrchr(b->arg, '/');
    snprintf(da, sizeof da, "%.*s", ba ? (int)(ba - a->arg) + 1 : 1, ba ? a->arg : ".");
    snprintf(db, sizeof db, "%.*s", bb ? (int)(bb - b->arg) + 1 : 1, bb ? b->arg : ".");
    return realpath(da, ra) && realpath(db, rb) && !strcmp(ra, rb) &&
           !strcmp(ba ? ba + 1 : a->arg, bb ? bb + 1 : b->arg);
}

/* The outputs (values of the options in `outputs`) and inputs (every other argument naming an
 * existing file) of argv; -1, or the usage error's exit status for an empty output path. */
static int collect(const char *cmd, const char *outputs, int argc, char **argv, named_file *out,
                   int *nout, struct stat *in, int *nin)
{
    char profile_path[PATH_MAX];
    *nout = *nin = 0;
    for (int i = 1; i < argc; ++i) {
        if (is_output_option(outputs, argv[i]) && i + 1 < argc) {
            const char *v = argv[++i];
            if (!v[0])
                return cli_usage_error(cmd, "%s: the path is empty", argv[i - 1]);
            if (!strcmp(v, "-") || *nout == MAX_PATHS) /* stdout */
                continue;
            out[*nout] = (named_file){v, argv[i - 1], 0, 0, 0};
            identify(&out[(*nout)++]);
            continue;
        }
        const char *a = argv[i];
        int axis, dir;
        double offset;
        if (i > 1 && !strcmp(argv[i - 1], "--profile") &&
            cli_parse_profile_placed(a, &axis, &dir, profile_path, sizeof profile_path,
                                     &offset) == 0)
            a = profile_path;
        if (*nin < MAX_PATHS && stat(a, &in[*nin]) == 0 && clash_kind(&in[*nin]))
            (*nin)++;
    }
    return -1;
}

/* The index of the input that out names, or -1. */
static int input_named(const named_file *out, const struct stat *in, int nin)
{
    for (int k = 0; k < nin; ++k)
        if (out->exists && out->dev == in[k].st_dev && out->ino == in[k].st_ino)
            return k;
    return -1;
}

int cli_check_output_paths(const char *cmd, const char *outputs, int argc, char **argv)
{
    named_file out[MAX_PATHS];
    struct stat in[MAX_PATHS]; /* the inputs: existing files, compared by device and inode */
    int nout, nin, rc = collect(cmd, outputs, argc, argv, out, &nout, in, &nin);
    if (rc >= 0)
        return rc;
    for (int o = 0; o < nout; ++o) {
        if (input_named(&out[o], in, nin) >= 0)
            return cli_usage_error(cmd, "%s %s: that file is also an input of this command "
                                        "(it would be replaced by the output)",
                                   out[o].opt, out[o].arg);
        for (int p = 0; p < o; ++p)
            if (same_file(&out[o], &out[p]))
                return cli_usage_error(cmd, "%s and %s name the same file %s: each output needs "
                                            "its own",
                                       out[p].opt, out[o].opt, out[o].arg);
    }
    return -1;
}

int cli_check_derived_output(const char *cmd, const char *outputs, const char *opt,
                             const char *path, int argc, char **argv)
{
    named_file out[MAX_PATHS], derived = {path, opt, 0, 0, 0};
    struct stat in[MAX_PATHS];
    int nout, nin, rc = collect(cmd, outputs, argc, argv, out, &nout, in, &nin);
    if (rc >= 0)
        return rc;
    identify(&derived);
    if (input_named(&derived, in, nin) >= 0)
        return cli_usage_error(cmd, "%s: the file it names, %s, is also an input of this command "
                                    "(it would be replaced by the output)",
                               opt, path);
    return -1;
}
