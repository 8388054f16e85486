/*
 * The UDP link of the native loop, of the native target and of python-can's hiludp bus (wire_bus.py): the hiludp
 * wire format (docs/protocol.md, "UDP datagrams and session handshake"). A data datagram is
 * session id (u32 LE) + header (id u32 LE, flags, link seq, payload length) + payload + CRC-16/CCITT (init
 * 0xFFFF, big endian, over header + payload); session 0 marks a control datagram (HELLO / ACK). Datagrams
 * from any address but the peer's and of any other session are dropped and counted. The socket is connect()ed
 * to the peer (by nl_udp_open; the target connects again on the HELLO it adopts), so the
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
    /* a bus end (nl_udp_open: python-can's hiludp): it proposes a session, adopts its peer's and counts drops */
    uint32_t proposal;         /* this end's session proposal not yet acknowledged (0: none) */
    int64_t next_hello_ns;     /* when the proposal's HELLO is sent again (CLOCK_MONOTONIC) */
    int32_t rejected;          /* the peer refused the proposal: 3 its key differs, 4 it does not authenticate */
    int32_t rcvbuf;            /* the socket's receive buffer as the kernel granted it [bytes] */
    int64_t kernel_drops;      /* datagrams the kernel dropped for this socket, buffer full (SO_RXQ_OVFL) */
} nl_udp_t;

/* Send one frame (FD frames with the FD and BRS flags); 0 ok, -1 counted error. */
int nl_udp_send(nl_udp_t *u, const hil_core_frame_t *f);

/* The next frame from the peer into *f: 1, or 0 when none came before deadline_ns (CLOCK_MONOTONIC; a
 * deadline in the past: only what is queued now). */
int nl_udp_recv(nl_udp_t *u, hil_core_frame_t *f, int64_t deadline_ns);

/* A bus end on a new socket: bound to bind_addr:local_port (0: any port), connect()ed to peer_addr:peer_port
 * (addresses and ports in network byte order), non-blocking, its receive buffer rcvbuf bytes (forced past
 * rmem_max where the process may, SO_RCVBUFFORCE; u->rcvbuf: what the kernel granted), kernel drops reported
 * (SO_RXQ_OVFL). *u is set up as a bus end: no session yet, it adopts its peer's HELLO and proposes its own on
 * the first send; authentication is set up after (hil_auth_init on u->auth). 0, or the errno of the failed call
 * (nothing left open). */
int32_t nl_udp_open(nl_udp_t *u, uint32_t bind_addr, uint16_t local_port, uint32_t peer_addr, uint16_t peer_port,
                    int32_t rcvbuf);

/* The bound local port (host byte order), 0 when unknown. */
uint16_t nl_udp_local_port(const nl_udp_t *u);

/* Close the socket of a bus end (idempotent: fd -1 after). */
void nl_udp_close(nl_udp_t *u);

/* Propose a fresh random session (HELLO, repeated by the receives every NL_UDP_HELLO_NS until acknowledged); on
 * an unauthenticated link the proposal is used at once (the peer adopts the HELLO before the frames after it). */
#define NL_UDP_HELLO_NS 100000000
void nl_udp_propose(nl_udp_t *u);

/* Send one frame of any kind (nl_wire_frame_t) from a bus end, proposing a session first when none is in use,
 * waiting until deadline_ns (CLOCK_MONOTONIC) while the socket's send buffer is full:
 * 0 sent; -1 a counted send error (errno says why); -2 a frame the wire cannot carry (counted as a send error);
 * -3 an authenticated link with no session agreed yet (receive until u->session is set, then send again). */
int nl_udp_send_wire(nl_udp_t *u, const nl_wire_frame_t *m, int64_t deadline_ns);

/* The next frame of any kind from the peer into *m: 1, or 0 when none came before deadline_ns (CLOCK_MONOTONIC;
 * in the past: only what is queued now). Also answers the handshake, repeats a pending HELLO and reads the
 * kernel's drop count (kernel_drops). */
int nl_udp_recv_wire(nl_udp_t *u, nl_wire_frame_t *m, int64_t deadline_ns);

/* *l: the link on *u. */
void nl_udp_link(nl_link_t *l, nl_udp_t *u);

#endif
