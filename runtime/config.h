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
} sc_config;

void sc_config_defaults(sc_config *c);

/* Set one option by its long name (without "--"); value NULL for a flag. 0, or -1 with why. */
int sc_config_set(sc_config *c, const char *key, const char *value, char *why, int whylen);

/* Read a configuration file; errors name the file and the line. 0 or -1. */
int sc_config_load_file(sc_config *c, const char *path, char *why, int whylen);

/* Parse argv: --config FILE is read first, then every other flag overrides it. Fills help=1 for
 * --help/-h, version=1 for --version. Checks the result (a table, at least one transport:
 * Modbus TCP 127.0.0.1:1502 when none is given). 0 or -1 with why. */
int sc_config_parse_args(sc_config *c, int argc, char **argv, int *help, int *version, char *why,
                         int whylen);

/* The usage text. */
extern const char sc_config_usage[];

#endif
