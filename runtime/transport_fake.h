/* runtime/transport_fake.h — an in-process transport for unit tests: the test holds one end of a
 * unix SOCK_SEQPACKET pair and the daemon's poll loop serves the other, like a real peer.
 * Request: 8 bytes, X and Y int32 nm (host byte order). Answer: 12 bytes, corrected X, Y int32,
 * status uint16, corrections mod 65536 uint16. A request of another size is counted and dropped. */
#ifndef SELFCALD_TRANSPORT_FAKE_H
#define SELFCALD_TRANSPORT_FAKE_H

#include <stdint.h>

#include "transport.h"

typedef struct sc_fake_answer {
    int32_t x_nm, y_nm;
    uint16_t status;
    uint16_t count;
} sc_fake_answer;

/* Make t the fake transport (static state, one instance). */
void sc_fake_transport(sc_transport *t);
/* The test's end of the pair (valid after open(); -1 before). */
int sc_fake_peer_fd(void);
/* Requests of a wrong size since open. */
uint32_t sc_fake_bad_requests(void);

#endif
