/* tests/fuzz/fuzz_selfcald_config.c — libFuzzer target: selfcald's configuration file
 * (sc_config_load_file). Errors are one line that names the file; a configuration that loads
 * has every value inside its documented range. */
#include <string.h>

#include "config.h"
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static sc_config c;
    sc_error err;
    sc_config_defaults(&c);
    sc_error_clear(&err);
    const char *path = fuzz_path(data, size);
    if (sc_config_load_file(&c, path, &err) != SC_OK) {
        FUZZ_CHECK(err.code != SC_OK && err.msg[0] != '\0' && strchr(err.msg, '\n') == NULL);
        FUZZ_CHECK(strcmp(err.file, path) == 0);
        return 0;
    }
    FUZZ_CHECK(c.tcp.max_connections >= 1 && c.tcp.max_connections <= SC_MBTCP_MAX_CONN);
    FUZZ_CHECK(c.tcp.max_per_peer >= SC_MBTCP_PER_PEER_AUTO && c.tcp.max_per_peer <= SC_MBTCP_MAX_CONN);
    FUZZ_CHECK(c.tcp.n_allow >= 0 && c.tcp.n_allow <= SC_MBTCP_MAX_ALLOW);
    FUZZ_CHECK(memchr(c.table, '\0', sizeof c.table) != NULL);
    FUZZ_CHECK(memchr(c.tcp.host, '\0', sizeof c.tcp.host) != NULL);
    FUZZ_CHECK(c.word_order == SC_WORD_HIGH_FIRST || c.word_order == SC_WORD_LOW_FIRST);
    return 0;
}
