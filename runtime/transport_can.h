/* runtime/transport_can.h — SocketCAN raw transport of selfcald (SPEC §4 "CAN"). */
#ifndef SELFCALD_TRANSPORT_CAN_H
#define SELFCALD_TRANSPORT_CAN_H

#include <stdint.h>

#include "transport.h"

typedef struct sc_can_config {
    char ifname[32];           /* e.g. "vcan0" */
    uint32_t in_id;            /* position in, default 0x100 */
    uint32_t out_id;           /* corrected position out, default 0x101 */
    uint32_t status_id;        /* status frame, default 0x102 */
    uint32_t status_period_ms; /* default 1000 */
} sc_can_config;

/* Fill c with the SPEC defaults (ids 0x100/0x101/0x102, 1 Hz status); ifname left empty. */
void sc_can_config_defaults(sc_can_config *c);

/* Make t the SocketCAN transport for cfg (state is static inside transport_can.c; one instance). */
void sc_can_transport(sc_transport *t, const sc_can_config *cfg);

#endif
