/* cli_opts.h — a command's options as a declarative table, parsed by one function (cli_opts.c).
 *
 * The table is the one list of what a command accepts: cli_opts_parse reads the command line by
 * it (usage errors as "selfcal CMD: ...", exit status 2), and cli_opts_print lists it (name,
 * value, kind, range, default, help), which `selfcal --options CMD` prints and from which the
 * OPTIONS lists of selfcal(1) are generated (tools/man_options.py; a test keeps them equal and
 * compares them with --help both ways).
 *
 * To add an option: one row in the command's table, e.g. (a made-up row of grid's table)
 *     {"--node-sigma", CLI_CHOICE, F(opt.node_sigma), "all|none", .choices = "all|none",
 *      .bad = "--node-sigma must be all or none, got '%s'", .def = "all",
 *      .help = "which nodes get an uncertainty"},
 * where F(field) is offsetof(the command's argument struct, field); then run
 * `python3 tools/man_options.py build/bin/selfcal docs/man/selfcal.1.in` to refresh the man page;
 * the command's --help lists it (cli_opts_help). A value the kinds below cannot check takes
 * CLI_CUSTOM and a parse function. */
#ifndef SELFCAL_CLI_OPTS_H
#define SELFCAL_CLI_OPTS_H

#include <stddef.h>
#include <stdio.h>

typedef enum {
    CLI_FLAG,   /* no value: the int field set to 1 (or, with a parse function, that called
                 * with the value NULL) */
    CLI_STRING, /* the value itself: a const char * field */
    CLI_LONG,   /* a whole number from min to max: a long field */
    CLI_INT,    /* a whole number from min to max: an int field */
    CLI_DOUBLE, /* a number from min to max (CLI_MIN_OPEN, CLI_MAX_OPEN: the end excluded) */
    CLI_CHOICE, /* one of choices ("a|b|c"): an int field, the index of the value */
    CLI_PAIR,   /* two numbers "A,B": a double[2] field */
    CLI_LIST,   /* repeatable: each value appended to a const char *[max] field; the count at
                 * count (an int), a value more than max is the usage error bad (%s: the value) */
    CLI_CUSTOM  /* the row's parse function */
} cli_kind;

enum { CLI_MIN_OPEN = 1u, CLI_MAX_OPEN = 2u };

/* A parse function: the value v of option opt into the field the row names (an operand: into
 * the command's argument struct): CLI_OK, or the exit status of the usage error it printed
 * (cli_usage_error with cmd). */
typedef int (*cli_opt_parse_fn)(const char *cmd, const char *opt, const char *v, void *field);

/* An option of two words ("--view SPEC FILE"): v the first, next the word after it (NULL at the
 * end); CLI_OK takes both, else the exit status of the usage error printed. */
typedef int (*cli_opt_parse2_fn)(const char *cmd, const char *opt, const char *v,
                                 const char *next, void *field);

/* The parse functions of values several commands take (cli_opts.c, on cli.c's parsers): --seed (a uint64_t), --max-memory
 * (a double of bytes), the least-squares options of cli_parse_lsq_option (the sc_grid_options). */
int cli_opt_seed(const char *cmd, const char *opt, const char *v, void *field);
int cli_opt_max_memory(const char *cmd, const char *opt, const char *v, void *field);
int cli_opt_lsq(const char *cmd, const char *opt, const char *v, void *field);
/* --max-nodes N (cli_parse_max_nodes, an int) */
int cli_opt_max_nodes(const char *cmd, const char *opt, const char *v, void *field);
/* A noise (cli_parse_noise, a double): from 0, or above 0 (_positive), to SC_INPUT_MAX_ABS. */
int cli_opt_noise(const char *cmd, const char *opt, const char *v, void *field);
int cli_opt_noise_positive(const char *cmd, const char *opt, const char *v, void *field);
/* The operand function of a command that takes none: "unknown option or missing value: WORD". */
int cli_opt_no_operand(const char *cmd, const char *opt, const char *v, void *args);

/* One option. Unset fields are zero (designated initializers). */
typedef struct cli_opt {
    const char *name;    /* "--map", or with aliases "-o|--out" (the first is the one documented) */
    cli_kind kind;
    size_t field;        /* offsetof(argument struct, the field the option sets) */
    const char *value;   /* the value's name in help and the man page ("G.csv", "N"); NULL: flag */
    double min, max;     /* CLI_LONG, CLI_INT, CLI_DOUBLE: the range (a CLI_CUSTOM row may state
                          * the range its function checks, for the listing); CLI_LIST: max values */
    unsigned ends;       /* CLI_MIN_OPEN | CLI_MAX_OPEN */
    const char *choices; /* CLI_CHOICE: "a|b|c"; another kind: the values it takes, as listed */
    const char *missing; /* the usage error of a missing value (format with the option), or NULL:
                          * the command's */
    const char *bad;     /* the usage error of a bad value (printf format: one %s, the value; two,
                          * the option and the value) */
    size_t count;        /* CLI_LIST: offsetof the int count */
    cli_opt_parse_fn parse; /* CLI_CUSTOM */
    cli_opt_parse2_fn parse2; /* CLI_CUSTOM of two words (instead of parse) */
    const char *def;     /* the default as the man page states it, or NULL */
    const char *help;    /* what it does, one line */
} cli_opt;

/* A command's table and the words of its generic usage errors (NULL: the usual words). */
typedef struct cli_cmd_opts {
    const char *cmd;        /* "grid", "report grid": the prefix of its usage errors */
    const char *usage;      /* --help's usage lines, a blank line and its prose (the option list
                             * between them is the table's: cli_opts_help) */
    const cli_opt *opts;
    int n_opts;
    size_t positional;      /* offsetof the const char * set by the one operand (a file) */
    cli_opt_parse_fn operand; /* instead: each operand passed to it (opt NULL) */
    const char *more;       /* a second operand: format with the first and the second */
    const char *missing;    /* an option without value: format with the option */
    const char *unknown;    /* an unknown option: format with the option */
    unsigned flags;         /* CLI_NO_OPERAND, CLI_NO_HELP, CLI_DASH_OPTION */
    const struct cli_cmd_opts *also; /* the table of another form of the command (plan --design),
                                      * listed with this one; NULL */
    cli_opt_parse_fn other; /* an option not in the table, with its value (field: the argument
                             * struct): its own usage error instead of unknown's; NULL */
} cli_cmd_opts;

enum {
    CLI_NO_OPERAND = 1u, /* every word is an option (a word not in the table: unknown) */
    CLI_NO_HELP = 2u,    /* --help is an option as any other (plan --design's second pass) */
    CLI_DASH_OPTION = 4u, /* a lone "-" is an option word (unknown), not an operand */
    CLI_STOP = -2        /* a parse function's "stop here": cli_opts_parse returns it */
};

/* Parse argv[1..argc-1] by the table into args (already holding the defaults): -1 to go on,
 * CLI_OK after --help, CLI_STOP where a parse function said so, else the exit status of the
 * usage error printed. */
int cli_opts_parse(const cli_cmd_opts *c, int argc, char **argv, void *args);

/* The command's --help on to: its usage text's first paragraph (the usage lines), "Options:" and
 * one line per row of the table (and its also's rows of other names: name, value, help, range,
 * default), then the rest of the usage text (the prose that is not per option). */
void cli_opts_help(FILE *to, const cli_cmd_opts *c);

/* The table (and its also's rows of other names), one option a line: name, value, kind, range,
 * default, help, tab-separated. */
void cli_opts_print(FILE *to, const cli_cmd_opts *c);

/* The commands' tables (in their cmd_*.c; main.c's command list points at them). */
extern const cli_cmd_opts cli_grid_opts, cli_profile_opts, cli_profile_plan_opts,
    cli_report_grid_opts, cli_report_profile_opts,
    cli_plot_map_opts, cli_plot_profile_opts, cli_plot_xy_opts, cli_simulate_profile_opts,
    cli_plan_opts, cli_lut_build_opts,
    cli_export_opts, cli_import_grid_opts, cli_import_profile_opts,
    cli_simulate_grid_opts, cli_simulate_exports_opts, cli_verify_opts;

#endif
