/* verify.h — the CLI's side of the check of a compensated machine (`selfcal verify`,
 * `report grid --verify`): its report section. The computation and the decision rule are the
 * library's (selfcal/verify.h). */
#ifndef SELFCAL_CLI_VERIFY_H
#define SELFCAL_CLI_VERIFY_H

#include <stdio.h>

#include "selfcal/verify.h"

/* The report section: model, statistics, decision rule, U and its parts, verdict, before/after
 * maps. name: the re-measurement as the user named it. */
sc_status verify_html_section(FILE *fp, const sc_verify_opts *o, const char *name,
                              const sc_verify_result *r, const char *heading, sc_error *err);

/* The verdict line of stdout and of the report: "pass (guarded, U = 0.02 um)". */
void verify_verdict_text(char *buf, size_t size, const sc_verify_result *r);

/* Parse --decision-rule, --u-verify-um, --u-plate-um and the re-measurement's noise (verify:
 * --sigma-r-um; report grid: --verify-sigma-um), the verification's options into o: CLI_OK, a usage error's code, or -1 when opt is none
 * of them. cmd names the command in messages. */
int verify_parse_option(const char *cmd, const char *opt, const char *val, sc_verify_opts *o);
/* The same as a parse function of an option table (cli_opts.h): field is the sc_verify_opts. */
int verify_parse_opt(const char *cmd, const char *opt, const char *val, void *field);

#endif
