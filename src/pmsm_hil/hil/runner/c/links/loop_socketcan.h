/*
 * The Linux SocketCAN link of the native loop and of the native target: a CAN_RAW socket moving
 * `struct can_frame` (classic CAN, 16 bytes) and `struct canfd_frame` (CAN FD with CAN_RAW_FD_FRAMES, 72 bytes)
 * exactly as python-can's socketcan interface writes and reads them (socketcan.build_can_frame /
 * capture_message) behind the host's BusLink: an FD frame with the FDF and BRS flags, a classic frame of at
 * most 8 bytes (the codec splits a Measurement / Command into parts on a classic link); extended, remote and
 * error frames are counted as ignored, what is not a frame of either size as a framing error. SocketCAN has no
 * link sequence numbers or CRC of its own (the bus has): LinkStats keeps frames, send errors, ignored and
 * framing errors, as for the Python link.
 *
 * The socket is the caller's (bound, its options set; python-can's for the host): any descriptor carrying
 * the same structs one per message works (the tests use a SOCK_SEQPACKET socketpair). Sending never waits
 * (a full transmit queue is a send error, as python-can's send without a timeout); waiting for a frame
 * busy-polls for at most spin_ns, then blocks in ppoll until the deadline. Every receive reads the kernel's drop
 * count of the socket (SO_RXQ_OVFL ancillary data, when the socket's owner turned it on) into kernel_dropped.
 * No allocation.
 */
#ifndef HIL_NATIVE_LOOP_SOCKETCAN_H
#define HIL_NATIVE_LOOP_SOCKETCAN_H

#include <stdint.h>

#include "nl_link.h"

typedef struct {
    int32_t fd;                /* CAN_RAW socket (or a SOCK_SEQPACKET end carrying the same structs) */
    int32_t fd_frames;         /* 1: CAN FD frames may be sent (CAN_RAW_FD_FRAMES is on) */
    nl_spin_t spin;            /* busy-poll, then block (adaptive, nl_link.h) */
    nl_link_stats_t stats;
    uint32_t kernel_dropped;   /* the kernel's count of frames dropped for the socket (SO_RXQ_OVFL), last seen */
    int32_t burst;             /* frames returned in a row at or past the deadline (NL_DRAIN_MAX bounds it) */
} nl_socketcan_t;

/* Send one frame; 0 ok, -1 counted error (an invalid length, an FD frame on a classic socket, a refused send). */
int nl_socketcan_send(nl_socketcan_t *s, const hil_core_frame_t *f);

/* The next 11-bit data frame into *f: 1; 0 when none came before deadline_ns; -1 when the peer closed (a
 * socketpair end: a zero-length read). At or past the deadline at most NL_DRAIN_MAX frames in a row come back
 * (then 0 once): a bus flooded by other nodes never empties, and the caller's deadline must still end its wait. */
int nl_socketcan_recv(nl_socketcan_t *s, hil_core_frame_t *f, int64_t deadline_ns);

/* *l: the link on *s. */
void nl_socketcan_link(nl_link_t *l, nl_socketcan_t *s);

#endif
