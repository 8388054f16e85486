/*
 * The native target: the C target core and reference firmware (firmware_stub/target/hil_target_core.c,
 * hil_app_reference.c) served on a link (nl_link.h: UDP in the target role, where the peer's HELLO agrees
 * the session; serial; SocketCAN) until SIGTERM/SIGINT, `idle_ns` without a frame, the exit of `parent_pid`
 * (the caller also asks for PR_SET_PDEATHSIG) or the peer closing the link. Waiting is the link's (a bounded
 * busy-poll, then blocking). No allocation.
 */
#ifndef HIL_NATIVE_TARGET_SERVE_H
#define HIL_NATIVE_TARGET_SERVE_H

#include <stdint.h>

#include "nl_link.h"

#define NT_END_SIGNAL 1
#define NT_END_PARENT 2
#define NT_END_IDLE 3
#define NT_END_CLOSED 4

/* Serve until an ending (NT_END_*); idle_ns 0: never idle, parent_pid 0: no parent check. */
int32_t nt_serve(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid);

#endif
