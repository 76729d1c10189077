/* cli_opts.c — one parser for every command's option table, and the table's listing (cli_opts.h). */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/csv.h"

/* Is name one of the aliases of o ("-o|--out")? */
static int opt_named(const cli_opt *o, const char *name)
{
    size_t n = strlen(name);
    for (const char *p = o->name; p;) {
        const char *bar = strchr(p, '|');
        size_t len = bar ? (size_t)(bar - p) : strlen(p);
        if (len == n && !strncmp(p, name, n))
            return 1;
        p = bar ? bar + 1 : NULL;
    }
    return 0;
}

static const cli_opt *find_opt(const cli_cmd_opts *c, const char *name)
{
    for (int k = 0; k < c->n_opts; ++k)
        if (opt_named(&c->opts[k], name))
            return &c->opts[k];
    return NULL;
}

static int in_range(const cli_opt *o, double x)
{
    int lo = (o->ends & CLI_MIN_OPEN) ? x > o->min : x >= o->min;
    int hi = (o->ends & CLI_MAX_OPEN) ? x < o->max : x <= o->max;
    return lo && hi;
}

/* The index of v among choices "a|b|c", or -1. */
static int choice_index(const char *choices, const char *v)
{
    size_t n = strlen(v);
    int k = 0;
    for (const char *p = choices; p; ++k) {
        const char *bar = strchr(p, '|');
        size_t len = bar ? (size_t)(bar - p) : strlen(p);
        if (len == n && !strncmp(p, v, n))
            return k;
        p = bar ? bar + 1 : NULL;
    }
    return -1;
}

/* The row's usage error for the value v: its format takes the value, or with two %s the option
 * and the value. */
static int bad_value(const cli_cmd_opts *c, const cli_opt *o, const char *name, const char *v)
{
    if (!o->bad)
        return cli_usage_error(c->cmd, "%s: bad value '%s' (see --help)", name, v);
    const char *first = strstr(o->bad, "%s");
    if (first && strstr(first + 2, "%s"))
        return cli_usage_error(c->cmd, o->bad, name, v);
    return cli_usage_error(c->cmd, o->bad, v);
}

/* A number option's value into its field: CLI_OK or the usage error. */
static int set_number(const cli_cmd_opts *c, const cli_opt *o, const char *name, const char *v,
                      char *field)
{
    if (o->kind == CLI_DOUBLE) {
        double x;
        if (sc_parse_double(v, &x) != SC_OK || !in_range(o, x))
            return bad_value(c, o, name, v);
        memcpy(field, &x, sizeof x);
        return CLI_OK;
    }
    long n;
    if (sc_parse_long(v, &n) != SC_OK || !in_range(o, (double)n))
        return bad_value(c, o, name, v);
    if (o->kind == CLI_INT) {
        int i = (int)n;
        memcpy(field, &i, sizeof i);
    } else {
        memcpy(field, &n, sizeof n);
    }
    return CLI_OK;
}

/* "A,B" into two numbers: 0, or -1 */
static int parse_pair(const char *v, double *ab)
{
    char buf[128];
    snprintf(buf, sizeof buf, "%s", v);
    char *comma = strchr(buf, ',');
    if (!comma)
        return -1;
    *comma = '\0';
    return sc_parse_double(buf, &ab[0]) || sc_parse_double(comma + 1, &ab[1]) ? -1 : 0;
}

/* The value v of option o (typed as name) into args: CLI_OK or the usage error. */
static int set_value(const cli_cmd_opts *c, const cli_opt *o, const char *name, const char *v,
                     void *args)
{
    char *field = (char *)args + o->field;
    switch (o->kind) {
    case CLI_STRING:
        memcpy(field, &v, sizeof v);
        return CLI_OK;
    case CLI_LONG:
    case CLI_INT:
    case CLI_DOUBLE:
        return set_number(c, o, name, v, field);
    case CLI_PAIR: {
        double ab[2];
        if (parse_pair(v, ab) != 0)
            return bad_value(c, o, name, v);
        memcpy(field, ab, sizeof ab);
        return CLI_OK;
    }
    case CLI_CHOICE: {
        int k = choice_index(o->choices, v);
        if (k < 0)
            return bad_value(c, o, name, v);
        memcpy(field, &k, sizeof k);
        return CLI_OK;
    }
    case CLI_LIST: {
        int *count = (int *)(void *)((char *)args + o->count);
        if (*count >= (int)o->max)
            return bad_value(c, o, name, v);
        memcpy(field + (size_t)*count * sizeof v, &v, sizeof v);
        ++*count;
        return CLI_OK;
    }
    case CLI_CUSTOM:
        return o->parse(c->cmd, name, v, field); /* two words: cli_opts_parse */
    case CLI_FLAG:
        break;
    }
    return CLI_OK;
}

/* An operand (a word not an option, or "-"): CLI_OK or the usage error. */
static int set_operand(const cli_cmd_opts *c, const char *a, void *args)
{
    if (c->operand)
        return c->operand(c->cmd, NULL, a, args);
    const char **slot = (const char **)(void *)((char *)args + c->positional);
    if (*slot)
        return cli_usage_error(c->cmd, c->more ? c->more : "more than one input file ('%s', '%s')",
                               *slot, a);
    *slot = a;
    return CLI_OK;
}

/* The usage error of an option without its value (or of an unknown option at the end). */
static int missing_value(const cli_cmd_opts *c, const cli_opt *o, const char *name)
{
    const char *fmt = o && o->missing ? o->missing
                      : c->missing    ? c->missing
                                      : "%s: unknown option or missing value (see --help)";
    return cli_usage_error(c->cmd, fmt, name);
}

/* A flag: its function called, or its int field set to 1. */
static int set_flag(const cli_cmd_opts *c, const cli_opt *o, const char *name, void *args)
{
    char *field = (char *)args + o->field;
    if (o->parse)
        return o->parse(c->cmd, name, NULL, field);
    int one = 1;
    memcpy(field, &one, sizeof one);
    return CLI_OK;
}

int cli_opts_parse(const cli_cmd_opts *c, int argc, char **argv, void *args)
{
    int words = !(c->flags & CLI_NO_OPERAND); /* a word is an operand */
    for (int a = 1; a < argc; ++a) {
        const char *name = argv[a];
        if (!(c->flags & CLI_NO_HELP) && (!strcmp(name, "--help") || !strcmp(name, "-h"))) {
            cli_opts_help(stdout, c);
            return CLI_OK;
        }
        const cli_opt *o = find_opt(c, name);
        int rc;
        if (o && o->kind == CLI_FLAG) {
            if ((rc = set_flag(c, o, name, args)) != CLI_OK)
                return rc;
            continue;
        }
        if (words && (name[0] != '-' || (!strcmp(name, "-") && !(c->flags & CLI_DASH_OPTION)))) {
            if ((rc = set_operand(c, name, args)) != CLI_OK)
                return rc;
            continue;
        }
        if (a + 1 >= argc)
            return missing_value(c, o, name);
        const char *v = argv[++a];
        if (!o && c->other)
            rc = c->other(c->cmd, name, v, args);
        else if (!o)
            rc = cli_usage_error(c->cmd, c->unknown ? c->unknown : "unknown option '%s' (see --help)",
                                 name);
        else if (o->parse2 && (rc = o->parse2(c->cmd, name, v, a + 1 < argc ? argv[a + 1] : NULL,
                                              (char *)args + o->field)) == CLI_OK)
            ++a; /* its second word */
        else if (!o->parse2)
            rc = set_value(c, o, name, v, args);
        if (rc != CLI_OK)
            return rc;
    }
    return -1;
}

static const char *const KIND_NAME[] = {"flag",   "string", "integer", "integer", "number",
                                        "choice", "pair",   "list",    "value"};

/* The values an option takes: its choices "a|b", the range of a number ("[2, 10000000]",
 * "(0, 1)", also of a CLI_CUSTOM row that states one), of a list "at most N"; else nothing. */
static void print_range(FILE *to, const cli_opt *o)
{
    int number = o->kind == CLI_LONG || o->kind == CLI_INT || o->kind == CLI_DOUBLE;
    if (o->choices)
        fputs(o->choices, to);
    else if (number || (o->kind == CLI_CUSTOM && o->min < o->max))
        fprintf(to, "%c%.10g, %.10g%c", (o->ends & CLI_MIN_OPEN) ? '(' : '[', o->min, o->max,
                (o->ends & CLI_MAX_OPEN) ? ')' : ']');
    else if (o->kind == CLI_LIST)
        fprintf(to, "at most %.0f", o->max);
}

static void print_row(FILE *to, const cli_opt *o)
{
    fprintf(to, "%s\t%s\t%s\t", o->name, o->value ? o->value : "", KIND_NAME[o->kind]);
    print_range(to, o);
    fprintf(to, "\t%s\t%s\n", o->def ? o->def : "", o->help ? o->help : "");
}

void cli_opts_print(FILE *to, const cli_cmd_opts *c)
{
    for (int k = 0; k < c->n_opts; ++k)
        print_row(to, &c->opts[k]);
    for (int k = 0; c->also && k < c->also->n_opts; ++k)
        if (!find_opt(c, c->also->opts[k].name))
            print_row(to, &c->also->opts[k]);
}

/* A number row's range in words: "in [2, 100]", "in (0, 1)", or with one end beyond any value
 * (past 1e15: LONG_MAX, infinity) "at least 1", "above 0", "at most 5"; whole numbers so
 * called. */
static void range_text(char *buf, size_t n, const cli_opt *o)
{
    const char *whole = o->kind == CLI_LONG || o->kind == CLI_INT ? "a whole number" : "";
    int no_min = o->min <= -1e15, no_max = o->max >= 1e15;
    if (no_max)
        snprintf(buf, n, "%s%s%s %.10g", whole, *whole ? ", " : "",
                 (o->ends & CLI_MIN_OPEN) ? "above" : "at least", o->min);
    else if (no_min)
        snprintf(buf, n, "%s%s%s %.10g", whole, *whole ? ", " : "", (o->ends & CLI_MAX_OPEN) ? "below" : "at most",
                 o->max);
    else
        snprintf(buf, n, "%s%sin %c%.10g, %.10g%c", whole, *whole ? " " : "", (o->ends & CLI_MIN_OPEN) ? '(' : '[',
                 o->min, o->max, (o->ends & CLI_MAX_OPEN) ? ')' : ']');
}

/* A row's help with what its value may be and its default, for --help ("... (a whole number in
 * [2, 10000000]; default: 1)"), as the man page's list says it (tools/man_options.py); choices
 * the value's name already shows ("a|b") are not repeated. */
static void help_text(char *buf, size_t n, const cli_opt *o)
{
    int number = (o->kind == CLI_LONG || o->kind == CLI_INT || o->kind == CLI_DOUBLE ||
                  (o->kind == CLI_CUSTOM && o->min < o->max && !o->choices)) &&
                 !(o->min <= -1e15 && o->max >= 1e15); /* any number: nothing to say */
    int choices = o->choices && !(o->value && strchr(o->value, '|'));
    char what[160] = "";
    if (number) {
        range_text(what, sizeof what, o);
    } else if (choices) {
        size_t w = (size_t)snprintf(what, sizeof what, "one of ");
        for (const char *p = o->choices; *p && w + 3 < sizeof what; ++p)
            w += (size_t)snprintf(what + w, sizeof what - w, *p == '|' ? ", " : "%c", *p);
    }
    char def[160] = "";
    if (o->def)
        snprintf(def, sizeof def, "%sdefault: %s", what[0] ? "; " : "", o->def);
    snprintf(buf, n, "%s%s%s%s%s", o->help ? o->help : "", what[0] || def[0] ? " (" : "", what,
             def, what[0] || def[0] ? ")" : "");
}

/* One row of --help's option list: "  --name VALUE" and its help from column HELP_COLUMN (on the
 * next line when the name is longer), wrapped at HELP_WIDTH. */
enum { HELP_COLUMN = 26, HELP_WIDTH = 100 };
static void help_row(FILE *to, const cli_opt *o)
{
    const char *bar = strchr(o->name, '|');
    int w = bar ? (int)(bar - o->name) : (int)strlen(o->name);
    int col = fprintf(to, "  %.*s%s%s", w, o->name, o->value ? " " : "", o->value ? o->value : "");
    char text[512];
    help_text(text, sizeof text, o);
    if (col + 2 > HELP_COLUMN) {
        fputc('\n', to);
        col = 0;
    }
    fprintf(to, "%*s", HELP_COLUMN - col, "");
    col = HELP_COLUMN;
    for (const char *p = text; *p;) {
        size_t word = strcspn(p, " ");
        if (col > HELP_COLUMN && col + 1 + (int)word > HELP_WIDTH) {
            fprintf(to, "\n%*s", HELP_COLUMN, "");
            col = HELP_COLUMN;
        } else if (col > HELP_COLUMN) {
            fputc(' ', to);
            ++col;
        }
        fprintf(to, "%.*s", (int)word, p);
        col += (int)word;
        p += word;
        p += strspn(p, " ");
    }
    fputc('\n', to);
}

void cli_opts_help(FILE *to, const cli_cmd_opts *c)
{
    const char *gap = strstr(c->usage, "\n\n");
    size_t head = gap ? (size_t)(gap - c->usage) + 1 : strlen(c->usage);
    fprintf(to, "%.*s\nOptions:\n", (int)head, c->usage);
    for (int k = 0; k < c->n_opts; ++k)
        help_row(to, &c->opts[k]);
    for (int k = 0; c->also && k < c->also->n_opts; ++k)
        if (!find_opt(c, c->also->opts[k].name))
            help_row(to, &c->also->opts[k]);
    if (gap)
        fputs(gap + 1, to);
}

/* A command without operands: anything left over is an unknown option (cli_opts.h). The parse
 * functions of values several commands take (cli_opt_seed, ...) are in cli.c, beside the value
 * parsers they call. */
int cli_opt_no_operand(const char *cmd, const char *opt, const char *v, void *args)
{
    (void)opt, (void)args;
    return cli_usage_error(cmd, "unknown option or missing value: %s (see --help)", v);
}
