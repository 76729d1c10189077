/* cli_values.c — the parse functions of the option values several commands take (cli_opts.h:
 * cli_opt_seed, cli_opt_max_memory, ...), the option tables' adapters to the value parsers of
 * cli.c. In their own file above both, so that the option parser (cli_opts.c) needs nothing of
 * cli.c but its usage error, and cli.c nothing of the tables. */
#include "cli.h"
#include "cli_opts.h"

int cli_opt_seed(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)opt;
    return cli_parse_seed(cmd, v, field);
}

int cli_opt_max_memory(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)opt;
    return cli_parse_max_memory(cmd, v, field);
}

int cli_opt_lsq(const char *cmd, const char *opt, const char *v, void *field)
{
    return cli_parse_lsq_option(cmd, opt, v, field);
}

int cli_opt_noise(const char *cmd, const char *opt, const char *v, void *field)
{
    return cli_parse_noise(cmd, opt, v, 0, field);
}

int cli_opt_noise_positive(const char *cmd, const char *opt, const char *v, void *field)
{
    return cli_parse_noise(cmd, opt, v, 1, field);
}


int cli_opt_max_nodes(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)opt;
    return cli_parse_max_nodes(cmd, v, field);
}
