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

#endif
