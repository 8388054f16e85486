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

#include "hil_target_core.h"
#include "loop.h"
#include "nl_link.h"

#define NT_END_SIGNAL 1
#define NT_END_PARENT 2
#define NT_END_IDLE 3
#define NT_END_CLOSED 4

/* Serve until an ending (NT_END_*); idle_ns 0: never idle, parent_pid 0: no parent check. */
int32_t nt_serve(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid);

/* The same loop over another copy of the core: a SIL library's hil_core_rx / hil_core_tx (`hil target --native
 * --sil PATH`, the SIL target in its own process; the caller loaded the library and called its hil_core_init). */
typedef void (*nt_core_rx_fn)(uint32_t id, const uint8_t *data, uint8_t len, uint8_t fd);
typedef int (*nt_core_tx_fn)(hil_core_frame_t *out);
int32_t nt_serve_core(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid, nt_core_rx_fn rx, nt_core_tx_fn tx);

/* nt_serve_core, and after each step (the core's step counter at *steps moved) its torque reference (*torque_ref,
 * the library's hil_app_cmd_t debug output) into *debug, memory the host maps too (loop.h nl_sil_debug_t), before
 * the step's Command is sent: how an isolated SIL run logs torque_ref. */
int32_t nt_serve_core_debug(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid, nt_core_rx_fn rx,
                            nt_core_tx_fn tx, const uint32_t *steps, const float *torque_ref, nl_sil_debug_t *debug);

#endif
