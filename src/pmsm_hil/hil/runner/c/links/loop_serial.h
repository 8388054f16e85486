/*
 * The serial link of the native loop, of the native target and of python-can's hilserial bus (wire_bus.py): the
 * hilserial wire format (docs/protocol.md, "Serial framing"): packet = COBS(header + payload +
 * CRC-16/CCITT-FALSE big endian) + 0x00, header = id u32 LE, flags, link seq, payload length; the framing of
 * firmware_stub/target/hil_serial.c. The receiver checks and counts (framing_errors, crc_errors, the
 * link seq check, ignored): it resynchronises at every 0x00 and drops a run of more than HIL_SERIAL_MAX_ENCODED
 * bytes without one, counted once.
 *
 * The descriptor is the caller's (a tty in raw mode as pyserial sets it up, or a pty master; non-blocking);
 * so is the state a run continues from (link seqs, a packet half received). Waiting for a frame busy-polls
 * for at most spin_ns, then blocks in ppoll until the deadline. No allocation.
 *
 * Authenticated frames (auth.on, docs/protocol.md "Authenticated frames"): the hil_auth trailer follows the
 * payload inside the COBS block (before the CRC); a run without a delimiter may then be 6 bytes longer.
 */
#ifndef HIL_NATIVE_LOOP_SERIAL_H
#define HIL_NATIVE_LOOP_SERIAL_H

#include <stdint.h>

#include "hil_auth.h"
#include "hil_serial.h"
#include "nl_link.h"

#define NL_SERIAL_READ 4096        /* bytes per read */
/* the longest packet between delimiters: an authenticated frame's (the trailer inside the COBS block) */
#define NL_SERIAL_MAX_ENCODED (HIL_SERIAL_MAX_ENCODED + HIL_AUTH_TRAILER)

typedef struct {
    int32_t fd;                /* the port (tty, pty master) */
    int32_t fd_frames;         /* 1: CAN FD frames may be sent (the bus's fd option) */
    hil_serial_t framer;       /* framer.tx_seq: next link sequence number sent */
    int32_t rx_last;           /* last link sequence number accepted, -1: none */
    nl_spin_t spin;            /* busy-poll, then block (adaptive, nl_link.h) */
    int64_t write_timeout_ns;  /* a full output buffer for this long: the frame is a send error */
    nl_link_stats_t stats;
    /* the deframer: the packet so far (pkt_n bytes), or discarding until the next 0x00 */
    uint8_t pkt[NL_SERIAL_MAX_ENCODED];
    int32_t pkt_n;
    int32_t discarding;
    /* bytes read but not fed yet */
    uint8_t rx[NL_SERIAL_READ];
    int32_t rx_at, rx_n;
    hil_auth_t auth;           /* authenticated frames (hil_auth.h; auth.on 0: off), no context */
} nl_serial_t;

/* Send one frame (an invalid length or an FD frame on a classic link is a send error);
 * 0 ok, -1 counted error. */
int nl_serial_send(nl_serial_t *s, const hil_core_frame_t *f);

/* The next frame into *f: 1; 0 when none came before deadline_ns; -1 when the peer closed (EIO). */
int nl_serial_recv(nl_serial_t *s, hil_core_frame_t *f, int64_t deadline_ns);

/* A bus end (python-can's hilserial) on the open descriptor fd (a tty in raw mode, a pty end), made non-blocking:
 * *s set up from nothing (link seqs from 0, no packet half received), CAN FD frames allowed when fd_frames, a
 * full output buffer for write_timeout_ns a send error; authentication is set up after (hil_auth_init on
 * s->auth). 0, or the errno of the failed call. */
int32_t nl_serial_attach(nl_serial_t *s, int32_t fd, int32_t fd_frames, int64_t write_timeout_ns);

/* Close the descriptor (idempotent: fd -1 after). */
void nl_serial_close(nl_serial_t *s);

/* Send one frame of any kind (nl_wire_frame_t): 0 sent; -1 a counted send error (errno says why); -2 a frame
 * the wire cannot carry, or an FD frame on a classic link (counted as a send error). */
int nl_serial_send_wire(nl_serial_t *s, const nl_wire_frame_t *m);

/* The next frame of any kind into *m: 1; 0 when none came before deadline_ns; -1 when the peer closed (EIO). */
int nl_serial_recv_wire(nl_serial_t *s, nl_wire_frame_t *m, int64_t deadline_ns);

/* *l: the link on *s. */
void nl_serial_link(nl_link_t *l, nl_serial_t *s);

#endif
