/* The floor of a lockstep exchange between two processes on this machine: a bare C ping-pong over UDP loopback,
 * no protocol, no plant, so that the native pair's rates (hil bench loop) can be judged against what the kernel
 * and the CPUs allow - spinning or blocking, idle or beside other load. */
#ifndef NL_LINK_FLOOR_H
#define NL_LINK_FLOOR_H

#include <stdint.h>

typedef struct {
    int64_t round_trips;      /* timed round trips */
    int64_t mean_ns;          /* mean round trip [ns] */
    int64_t max_ns;           /* longest round trip [ns] */
} nl_udp_floor_t;

/* `n` round trips of a 32-byte datagram between this process and a forked echo child, both waiting for each
 * datagram by busy-polling for at most spin_ns, then blocking in ppoll (spin_ns 0: always block). 0 ok, else
 * the errno of the failed call. */
int32_t nl_udp_floor(int64_t n, int64_t spin_ns, nl_udp_floor_t *out);

/* The floor under a real-time run's deadline misses over UDP: what a bare C exchange paced as the run is sees. */
typedef struct {
    int64_t periods;          /* periods paced (a datagram sent at each start) */
    int64_t late;             /* replies that had not come by the next period start (a run's deadline miss) */
    int64_t max_ns;           /* longest round trip [ns] */
    int64_t median_ns;        /* median round trip [ns] (1 us bins) */
} nl_udp_paced_floor_t;

/* For `n` periods of `period_ns`, this thread (on `cpu` if >= 0, at SCHED_FIFO `rt_priority` if > 0, as the
 * run's loop) busy-waits to each period start, sends a 32-byte datagram to a forked echo child (at the same
 * priority, unpinned; waiting for each datagram by busy-polling for at most echo_spin_ns, then blocking in ppoll,
 * as the run's native target) and busy-polls for the reply until the next period start: a reply not there by
 * then is `late` (the run's deadline miss) and is waited for before the next send (the schedule goes on from
 * the period after it). 0 ok, else the errno of the failed call (a refused priority or CPU is not a failure). */
int32_t nl_udp_paced_floor(int64_t n, int64_t period_ns, int32_t cpu, int32_t rt_priority, int64_t echo_spin_ns,
                           nl_udp_paced_floor_t *out);

#endif
