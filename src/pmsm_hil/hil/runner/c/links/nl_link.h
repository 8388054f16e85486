/*
 * One link of the native loop and of the native target: send a frame, receive the next one until a deadline,
 * behind two function pointers and the link's own state (`ctx`). A link is one file (loop_udp.c, loop_serial.c,
 * loop_socketcan.c) that fills an nl_link_t; the loop (loop.c) and the target's serve loop (target_serve.c)
 * only call through it. Also what every link shares: the LinkStats counters (src/pmsm_hil/protocol/links/stats.py, same
 * names), the 8-bit link sequence check, the payload-length rule, and the wait for a readable
 * descriptor: a bounded busy-poll, then ppoll until the deadline, so a loaded machine degrades instead of
 * collapsing. No allocation.
 */
#ifndef HIL_NATIVE_NL_LINK_H
#define HIL_NATIVE_NL_LINK_H

#include <stddef.h>
#include <stdint.h>

#include "hil_auth.h"
#include "hil_target_core.h"

/* Send one frame: 0 ok, -1 a counted error (send_errors). */
typedef int (*nl_send_fn)(void *ctx, const hil_core_frame_t *f);
/* The next frame into *f (payload bytes past len zeroed): 1; 0 when none came before deadline_ns
 * (CLOCK_MONOTONIC; a deadline in the past: only what is queued now); -1 when the peer closed the link. */
typedef int (*nl_recv_fn)(void *ctx, hil_core_frame_t *f, int64_t deadline_ns);

/* A link that can be flooded by other nodes (SocketCAN) returns at most this many frames in a row at or past a
 * receive's deadline, then 0 once: a drain or a wait ends even when the queue never empties. */
#define NL_DRAIN_MAX 256

/* What an in-process target says of the step that produced the last reply (the C target core's profiled step, or
 * the Python loop's `inproc_result`): its stage split [ns], torque reference [N*m] and restricted-vs-full candidate
 * miss (255: not checked); 1 filled, 0 nothing to say. NULL on links to another process (no split crosses a wire). */
typedef int (*nl_diag_fn)(void *ctx, uint32_t *split_ns, double *torque_ref, uint8_t *full_miss);

/* A period starts at run time t_s [s] (k * Ts): called just before its Measurement is sent, where the Python
 * loop sets the clock link fault injection reads. NULL on links that need no clock. */
typedef void (*nl_period_fn)(void *ctx, double t_s);

/* What a link is (nl_link_t.flags). NL_LINK_IN_PROCESS: its peer answers inside `send` / `recv` in this process
 * (the C target core, link_core.h): a receive that found nothing will find nothing later, so a real-time period
 * without a reply waits out its deadline, and the first period needs no synchronising exchange. 0: the peer is
 * another process or a board, its replies take wall time. */
#define NL_LINK_IN_PROCESS 1u

typedef struct nl_link {
    nl_send_fn send;
    nl_recv_fn recv;
    void *ctx;
    nl_diag_fn diag;
    nl_period_fn period;
    uint32_t flags;            /* NL_LINK_* */
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
        l->diag = NULL;                                                                                  \
        l->period = NULL;                                                                                \
        l->flags = 0u;                                                                                   \
    }

/* LinkStats (src/pmsm_hil/protocol/links/stats.py), plus the waits that ended in ppoll. */
typedef struct {
    int64_t frames_tx, frames_rx, crc_errors, framing_errors, dropped, duplicate, out_of_order, send_errors,
        ignored, foreign_dropped, session_dropped, auth_failed, auth_replayed;
    int64_t blocked;           /* waits that ended in ppoll (the spin found nothing) */
} nl_link_stats_t;

/* The link sequence check on *last (-1: none yet): 1 deliver, 0 a repeat; dropped / duplicate / out_of_order counted. */
int nl_seq_accept(int32_t *last, uint8_t seq, nl_link_stats_t *st);

/* hil_auth_open on a received body of n bytes ending in its trailer: 1 accepted, 0 dropped and counted
 * (auth_failed: a MAC that does not match; auth_replayed: a stale freshness value). */
int nl_auth_open(hil_auth_t *a, const uint8_t *body, size_t n, nl_link_stats_t *st);

/* A classic (<= 8) or CAN FD payload length. */
int nl_valid_length(uint8_t n, int fd);

/* A header + payload of the UDP and serial framings (src/pmsm_hil/protocol/links/wire.py:
 * id u32 LE, flags, link seq, payload length) whose CRC and length field were checked: a payload length no
 * classic / FD frame has is a framing error; then the link seq check; then extended or remote frames are
 * ignored. 1 when *f got a data frame (payload past len zeroed). */
int nl_accept_framed(const uint8_t *body, int32_t *rx_last, nl_link_stats_t *st, hil_core_frame_t *f);

/* A frame of the hiludp / hilserial wire with every flag it carries (what a python-can bus moves; the loop's
 * hil_core_frame_t is the 11-bit data frame only). A remote frame has no payload: its `len` is its DLC (0..8),
 * sent as that many zero bytes so the wire's length rule holds (docs/protocol.md). */
#define NL_WIRE_FD 0x01u
#define NL_WIRE_BRS 0x02u
#define NL_WIRE_ESI 0x04u
#define NL_WIRE_EXTENDED 0x08u
#define NL_WIRE_REMOTE 0x10u
#define NL_WIRE_FLAGS 0x1Fu
#define NL_WIRE_HEADER 7
typedef struct {
    uint32_t id;               /* arbitration id (11 or 29 bits) */
    uint8_t flags;             /* NL_WIRE_* */
    uint8_t len;               /* payload bytes; a remote frame: its DLC */
    uint8_t data[HIL_CORE_MAX_PAYLOAD];
} nl_wire_frame_t;

/* Header (link seq `seq`) + payload of *m into body (NL_WIRE_HEADER + len bytes, a remote frame's payload zero);
 * returns that length, or 0 for a frame the wire cannot carry (a length no classic / FD frame has, BRS or ESI
 * without FD, a remote FD frame, flags outside NL_WIRE_FLAGS). */
size_t nl_wire_pack(const nl_wire_frame_t *m, uint8_t seq, uint8_t *body);

/* nl_accept_framed for a bus: the same length and link seq checks, then every frame (extended, remote, FD with
 * or without BRS, ESI) into *m. 1 when *m got a frame. */
int nl_accept_wire(const uint8_t *body, int32_t *rx_last, nl_link_stats_t *st, nl_wire_frame_t *m);

/* How long a receive busy-polls before it blocks, adapted to the machine. Spinning wins on an idle machine
 * (a blocked process on a halted vCPU wakes tens of µs late); blocking wins when the CPU is contended: a
 * spinning end then takes a core from the peer or from the load, while two ends that block leave a core idle
 * for whichever of them is woken (and a busy CPU wakes a blocked thread quickly). Over a window of
 * NL_SPIN_WINDOW receives that waited, the time the thread was runnable but not running (wall time - its CPU
 * time - time blocked in ppoll) and the spins that ran out shortly before the frame came (it came less than
 * NL_SPIN_NEAR_MISS_NS after: a slowed peer, not one that had nothing to send - a host between runs, a
 * Setpoint from Python) are counted. A window is contended when the first exceeds a quarter of it or the
 * second half of its receives; after two contended windows in a row the next receives block at once:
 * NL_SPIN_BACKOFF of them, doubled (up to NL_SPIN_BACKOFF_DOUBLINGS times) for each back-off that follows
 * without a clean window in between, then spinning is tried again. A back-off ends early (and the next one is
 * the shortest again) when, over NL_SPIN_CHECK receives, blocking waited longer per receive than the spinning of
 * the window that started it: the load went away, or the window only looked contended (the run's own drain),
 * and a blocked receive now waits for an idle CPU to wake. Counted in receives, not in time: the two
 * ends of a lockstep link receive alike, so they back off and try again together (an end that spins while its
 * peer blocks sees its spins run out and would back off again). The window is short because its receives are the
 * price of noticing the load: beside a CPU burner both ends spin ~100 µs per receive until they back off (two
 * windows of 256 cost a 1 s lockstep run ~20 % of its rate; 128: idle rate unchanged, loaded +11-17 %; 64: false
 * back-offs on an idle machine, idle rate -35 %; docs/benchmarks.md). All zero: spinning, no history. */
#define NL_SPIN_WINDOW 128
#define NL_SPIN_BACKOFF 4096
#define NL_SPIN_BACKOFF_DOUBLINGS 4
#define NL_SPIN_NEAR_MISS_NS 1000000
#define NL_SPIN_CHECK 64
typedef struct {
    int64_t spin_ns;           /* busy-poll at most this long before blocking (0: always block) */
    int64_t window_wall_ns;    /* CLOCK_MONOTONIC at the start of the current window */
    int64_t window_cpu_ns;     /* the thread's CPU time at the start of the current window */
    int64_t window_blocked_ns; /* time spent in ppoll in the current window */
    int32_t window_n;          /* receives that waited in the current window */
    int32_t window_spun_out;   /* receives of the window whose spin ran out shortly before the frame came */
    int32_t block_left;        /* receives left that block at once */
    int32_t contended;         /* contended windows in a row */
    int32_t spinning;          /* the current receive spins (not yet counted as run out) */
    int32_t doublings;         /* the next back-off is NL_SPIN_BACKOFF << doublings */
    int32_t rx_backed_off;     /* the current receive blocks at once (backed off) */
    int32_t check_n;           /* receives of the current back-off check */
    int64_t rx_start_ns;       /* the current receive's first wait (0: none yet) */
    int64_t rx_last_ns;        /* its last poll */
    int64_t window_wait_ns;    /* the waits of the window's receives (each from its first wait to its last poll) */
    int64_t spin_wait_ns;      /* mean wait of a receive in the window that started the back-off */
    int64_t check_wait_ns;     /* the waits of the current back-off check's receives */
    int64_t backoffs;          /* times the link went to blocking at once */
    int64_t early_ends;        /* back-offs ended early: blocking waited longer than spinning had */
} nl_spin_t;

/* Nothing to read on `fd`: 0 once deadline_ns has passed, else 1 after busy-polling (until *spin_end, set on
 * the first call of a receive from *sp: start it at -1) or blocking in ppoll until the deadline or input
 * (counted in st->blocked); -1 when ppoll reported a hang-up or an error (input may be there too). */
int nl_wait_readable(int32_t fd, int64_t deadline_ns, nl_spin_t *sp, int64_t *spin_end, nl_link_stats_t *st);

#endif
