/* runtime/transport_can.h — SocketCAN raw transport of selfcald (SPEC §4 "CAN").
 *
 * Frames (classic CAN, 11-bit ids, little-endian, nanometres; described in runtime/selfcald.dbc):
 *   in_id     (0x100) in,  DLC 8: X int32, Y int32
 *   out_id    (0x101) out, DLC 8: corrected X int32, Y int32, one per valid in_id frame
 *   status_id (0x102) out, DLC 8, every status_period_ms: status bits (byte 0), reserved (byte 1),
 *             bad frames since start (uint16 LE, bytes 2-3, modulo 65536), corrections since start
 *             (uint32 LE, bytes 4-7).
 * Status byte 0: bits 0-5 are the engine's status bits (as the Modbus status register); bit 6
 * (SC_CAN_ST_BUS_OFF) and bit 7 (SC_CAN_ST_LOST) are CAN-only extensions, see below.
 * A "bad" frame is any frame that is not a valid position frame: an in_id frame with a DLC other
 * than 8, a remote frame, an extended-format frame, a frame on out_id/status_id sent by another
 * node (an id conflict), and a frame on any other id (SPEC: "a bad DLC or id"). Bad frames are
 * counted and answered with nothing. With ignore_other_ids (a bus shared with other traffic) the
 * kernel filters (CAN_RAW_FILTER) pass only our three numbers: other ids are neither seen nor
 * counted.
 * CAN FD frames are accepted on FD-capable interfaces: an FD in_id frame of length 8 is answered with
 * an FD out_id frame of length 8; any other length is bad.
 */
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
    int ignore_other_ids;      /* 1: frames on other ids filtered out, not counted as bad */
    /* Optional log sink (prio: syslog LOG_* level; msg without newline). NULL: the daemon's
     * log (runtime/log.h: stderr or syslog). */
    void (*log)(int prio, const char *msg);
} sc_can_config;

/* CAN-only bits of status byte 0 (the engine's bits 0-5 are passed through). */
#define SC_CAN_ST_BUS_OFF 0x40u /* the controller is bus-off, or was since the last status frame */
#define SC_CAN_ST_LOST 0x80u    /* since the last status frame: an input frame was dropped by the
                                   kernel (we read too slowly) or an output frame could not be queued */

/* Fill c with the SPEC defaults (ids 0x100/0x101/0x102, 1 Hz status); ifname left empty. */
void sc_can_config_defaults(sc_can_config *c);

/* Make t the SocketCAN transport for cfg (state is static inside transport_can.c; one instance). */
void sc_can_transport(sc_transport *t, const sc_can_config *cfg);

/* Counters of the transport (since start), for logs and tests. */
typedef struct sc_can_stats {
    uint32_t rx_frames;     /* frames read (after the kernel filter), error frames included */
    uint32_t positions;     /* valid position frames (each answered) */
    uint32_t bad_frames;    /* bad DLC or id (the status frame carries the low 16 bits) */
    uint32_t tx_frames;     /* frames handed to the kernel */
    uint32_t tx_queue_full; /* sends refused with ENOBUFS/EAGAIN (the frame stays queued, retried) */
    uint32_t tx_dropped;    /* output frames given up: retry queue full or a hard send error */
    uint64_t rx_overflow;   /* input frames the kernel dropped because the socket was full */
    uint32_t error_frames;  /* CAN error frames received */
    uint32_t bus_off;       /* bus-off events */
    uint32_t reopened;      /* times the socket was reopened (interface removed and back) */
    int bus_off_now;        /* 1 while the controller is bus-off */
    int link_down_now;      /* 1 while the interface is down or gone */
} sc_can_stats;

/* Copy the transport's counters into *s. */
void sc_can_get_stats(sc_can_stats *s);

/* Frame payloads (8 bytes, little-endian). */
void sc_can_encode_position(uint8_t data[8], int32_t x_nm, int32_t y_nm);
void sc_can_decode_position(const uint8_t data[8], int32_t *x_nm, int32_t *y_nm);
void sc_can_encode_status(uint8_t data[8], uint8_t status_bits, uint16_t bad_frames,
                          uint32_t corrections);

/* How the transport treats a received frame (can_id with the kernel's flag bits, len = DLC). */
typedef enum sc_can_rx_kind {
    SC_CAN_RX_POSITION = 0, /* a valid position frame: answer it */
    SC_CAN_RX_BAD = 1,      /* bad DLC or id: count it, answer nothing */
    SC_CAN_RX_ERROR = 2,    /* a CAN error frame (bus state) */
    SC_CAN_RX_IGNORE = 3    /* not ours (the kernel filter should not let it through) */
} sc_can_rx_kind;
sc_can_rx_kind sc_can_classify(const sc_can_config *c, uint32_t can_id, uint8_t len);

/* Check a configuration: ids 11-bit and distinct, ifname set, period > 0. SC_OK, or SC_E_INPUT
 * with the reason in err. */
sc_status sc_can_config_check(const sc_can_config *c, sc_error *err);

/* For tests: make open() use fd (e.g. one end of a SOCK_SEQPACKET socketpair carrying struct
 * can_frame / canfd_frame datagrams) instead of a CAN socket. fd < 0 restores normal behaviour. */
void sc_can_transport_use_fd(int fd);

#endif
