/*
 * The native target: the C target core and reference firmware (firmware_stub/target/hil_target_core.c,
 * hil_app_reference.c) served on a UDP link (loop_udp.h, target role: the peer's HELLO agrees the session)
 * until SIGTERM/SIGINT, `idle_ns` without a frame, or the exit of `parent_pid` (the caller also asks for
 * PR_SET_PDEATHSIG). Waiting busy-polls for spin_ns, then blocks. No allocation.
 */
#ifndef HIL_NATIVE_TARGET_UDP_H
#define HIL_NATIVE_TARGET_UDP_H

#include <stdint.h>

#include "loop_udp.h"

#define NT_END_SIGNAL 1
#define NT_END_PARENT 2
#define NT_END_IDLE 3

/* Serve until an ending (NT_END_*); idle_ns 0: never idle, parent_pid 0: no parent check. */
int32_t nt_serve(nl_udp_t *u, int64_t idle_ns, int32_t parent_pid);

#endif
