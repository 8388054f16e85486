/*
 * The UDP link of the native loop and of the native target: the hiludp wire format of
 * src/pmsm_hil/protocol/links/udp_bus.py (docs/protocol.md, "UDP datagrams and session handshake"). A data datagram is
 * session id (u32 LE) + header (id u32 LE, flags, link seq, payload length) + payload + CRC-16/CCITT (init
 * 0xFFFF, big endian, over header + payload); session 0 marks a control datagram (HELLO / ACK). Datagrams
 * from any address but the peer's and of any other session are dropped and counted. The socket is connect()ed
 * to the peer (by Python's hiludp when it opens; the target connects again on the HELLO it adopts), so the
 * kernel drops other senders' datagrams before they reach it.
 *
 * The socket is the caller's (bound, non-blocking); the session was agreed before (the host: Python's
 * handshake) or is agreed here (the target: a HELLO from the peer is adopted and acknowledged). Waiting for
 * a frame busy-polls for at most spin_ns, then blocks in ppoll until the deadline, so a loaded machine
 * degrades instead of collapsing. No allocation.
 *
 * Authenticated frames (auth.on, docs/protocol.md "Authenticated frames"): every data datagram carries the
 * hil_auth trailer between payload and CRC, control datagrams a nonce and a MAC (22 bytes); a HELLO whose MAC
 * fails (or that is unauthenticated on an authenticating end, or authenticated on one that is not) is answered
 * with a REJECT naming why, and counted in auth_failed; frames whose MAC fails or whose freshness is stale are
 * dropped and counted (auth_failed, auth_replayed).
 */
#ifndef HIL_NATIVE_LOOP_UDP_H
#define HIL_NATIVE_LOOP_UDP_H

#include <stdint.h>

#include "hil_auth.h"
#include "nl_link.h"

typedef struct {
    int32_t fd;                /* bound UDP socket */
    uint32_t session;          /* agreed session id (0: none yet; the target adopts the peer's HELLO) */
    uint32_t peer_addr;        /* peer IPv4 address, network byte order */
    uint16_t peer_port;        /* peer port, network byte order */
    uint8_t tx_seq;            /* next link sequence number sent */
    int32_t target_role;       /* 1: adopt and acknowledge the peer's HELLO; 0 (host): count it as dropped */
    int32_t rx_last;           /* last link sequence number accepted, -1: none */
    nl_spin_t spin;            /* busy-poll, then block (adaptive, nl_link.h) */
    nl_link_stats_t stats;
    uint32_t nonce;            /* the adopting end's nonce of the session (authenticated links; the target's) */
    hil_auth_t auth;           /* authenticated frames (hil_auth.h; auth.on 0: off), context = session + nonce */
} nl_udp_t;

/* Send one frame (FD frames with the FD and BRS flags, as FramedBus.send_frame); 0 ok, -1 counted error. */
int nl_udp_send(nl_udp_t *u, const hil_core_frame_t *f);

/* The next frame from the peer into *f: 1, or 0 when none came before deadline_ns (CLOCK_MONOTONIC; a
 * deadline in the past: only what is queued now). */
int nl_udp_recv(nl_udp_t *u, hil_core_frame_t *f, int64_t deadline_ns);

/* *l: the link on *u. */
void nl_udp_link(nl_link_t *l, nl_udp_t *u);

#endif
