/* runtime/config.h — selfcald's settings: a configuration file ("key = value" lines, '#'
 * comments, the keys are the long option names) and command-line flags, which win. */
#ifndef SELFCALD_CONFIG_H
#define SELFCALD_CONFIG_H

#include "engine.h"
#include "modbus_map.h"
#include "transport_can.h"
#include "transport_modbus.h"

typedef struct sc_config {
    char table[512];
    sc_corr_mode mode;
    int use_modbus_tcp, use_modbus_rtu, use_can;
    sc_mbtcp_config tcp;
    sc_mbrtu_config rtu;
    sc_can_config can;
    sc_word_order word_order;
    int use_syslog;
    char syslog_socket[108]; /* default /dev/log */
    int log_level; /* SC_LOG_* */
    uint32_t busy_poll_us; /* after activity, poll without sleeping this long (0 = off) */
    /* plausibility bounds of a table (0 = none): --max-correction-um, --max-gradient-um-per-mm */
    double max_correction_um;
    double max_gradient_um_per_mm;
} sc_config;

void sc_config_defaults(sc_config *c);

/* Set one option by its long name (without "--"); value NULL for a flag. SC_OK, or SC_E_INPUT
 * (or SC_E_IO when a host name cannot be resolved) with the reason in err. */
sc_status sc_config_set(sc_config *c, const char *key, const char *value, sc_error *err);

/* Read a configuration file: SC_OK, or an error whose file and line (err->file, err->line) are
 * the file's and the offending line's (SC_E_IO if it cannot be opened). */
sc_status sc_config_load_file(sc_config *c, const char *path, sc_error *err);

/* Parse argv: --config FILE is read first, then every other flag overrides it. Fills help=1 for
 * --help/-h, version=1 for --version. Checks the result (a table, at least one transport:
 * Modbus TCP 127.0.0.1:1502 when none is given). SC_OK or an error described in err. */
sc_status sc_config_parse_args(sc_config *c, int argc, char **argv, int *help, int *version,
                               sc_error *err);

/* The usage text. */
extern const char sc_config_usage[];

#endif
