/*
 * One link of the native loop and of the native target: send a frame, receive the next one until a deadline,
 * behind two function pointers and the link's own state (`ctx`). A link is one file (loop_udp.c, loop_serial.c,
 * loop_socketcan.c) that fills an nl_link_t; the loop (loop.c) and the target's serve loop (target_serve.c)
 * only call through it. Also what every link shares: the LinkStats counters (protocol/links/stats.py, same
 * names), the 8-bit link sequence check (SeqTracker), the payload-length rule, and the wait for a readable
 * descriptor: a bounded busy-poll, then ppoll until the deadline, so a loaded machine degrades instead of
 * collapsing. No allocation.
 */
#ifndef HIL_NATIVE_NL_LINK_H
#define HIL_NATIVE_NL_LINK_H

#include <stdint.h>

#include "hil_target_core.h"

/* Send one frame: 0 ok, -1 a counted error (send_errors). */
typedef int (*nl_send_fn)(void *ctx, const hil_core_frame_t *f);
/* The next frame into *f (payload bytes past len zeroed): 1; 0 when none came before deadline_ns
 * (CLOCK_MONOTONIC; a deadline in the past: only what is queued now); -1 when the peer closed the link. */
typedef int (*nl_recv_fn)(void *ctx, hil_core_frame_t *f, int64_t deadline_ns);

typedef struct nl_link {
    nl_send_fn send;
    nl_recv_fn recv;
    void *ctx;
} nl_link_t;

/* Defines `void PREFIX_link(nl_link_t *l, TYPE *state)` for a link file with
 * `int PREFIX_send(TYPE *, const hil_core_frame_t *)` and `int PREFIX_recv(TYPE *, hil_core_frame_t *, int64_t)`. */
#define NL_LINK_DEFINE(prefix, type)                                                                     \
    static int prefix##_send_any(void *ctx, const hil_core_frame_t *f)                                   \
    {                                                                                                    \
        return prefix##_send((type *)ctx, f);                                                            \
    }                                                                                                    \
    static int prefix##_recv_any(void *ctx, hil_core_frame_t *f, int64_t deadline_ns)                    \
    {                                                                                                    \
        return prefix##_recv((type *)ctx, f, deadline_ns);                                               \
    }                                                                                                    \
    void prefix##_link(nl_link_t *l, type *state)                                                        \
    {                                                                                                    \
        l->send = prefix##_send_any;                                                                     \
        l->recv = prefix##_recv_any;                                                                     \
        l->ctx = state;                                                                                  \
    }

/* LinkStats (protocol/links/stats.py), plus the waits that ended in ppoll. */
typedef struct {
    int64_t frames_tx, frames_rx, crc_errors, framing_errors, dropped, duplicate, out_of_order, send_errors,
        ignored, foreign_dropped, session_dropped;
    int64_t blocked;           /* waits that ended in ppoll (the spin found nothing) */
} nl_link_stats_t;

/* SeqTracker.accept on *last (-1: none yet): 1 deliver, 0 a repeat; dropped / duplicate / out_of_order counted. */
int nl_seq_accept(int32_t *last, uint8_t seq, nl_link_stats_t *st);

/* valid_payload_length: a classic (<= 8) or CAN FD payload length. */
int nl_valid_length(uint8_t n, int fd);

/* FramedBus._accept + poll_frame on a header + payload of the UDP and serial framings (protocol/links/wire.py:
 * id u32 LE, flags, link seq, payload length) whose CRC and length field were checked: a payload length no
 * classic / FD frame has is a framing error; then the link seq check; then extended or remote frames are
 * ignored. 1 when *f got a data frame (payload past len zeroed). */
int nl_accept_framed(const uint8_t *body, int32_t *rx_last, nl_link_stats_t *st, hil_core_frame_t *f);

/* Nothing to read on `fd`: 0 once deadline_ns has passed, else 1 after busy-polling (until *spin_end, set to
 * now + spin_ns on the first call of a receive: start it at -1) or blocking in ppoll until the deadline or
 * input (counted in st->blocked); -1 when ppoll reported a hang-up or an error (input may be there too). */
int nl_wait_readable(int32_t fd, int64_t deadline_ns, int64_t spin_ns, int64_t *spin_end, nl_link_stats_t *st);

#endif
