/*
 * The Python glue of the native loop's cffi extension (pmsm_hil.hil._loop_native): included once, by the
 * extension's preamble (src/pmsm_hil/hil/runner/c/_build_loop.py), which takes the cffi declarations of these functions from
 * here. Sizes and pointers into a ring slot for numpy views, and the callback link: any Python link (python-can
 * adapters, links to in-process, SIL and QEMU targets, the fault-injecting wrapper) carries the C loop's frames
 * through nl_py_send / nl_py_recv, which src/pmsm_hil/hil/runner/callback_link.py defines (cffi `extern "Python"`: cffi
 * writes their C bodies after this header).
 */
#ifndef HIL_NATIVE_LOOP_PY_H
#define HIL_NATIVE_LOOP_PY_H

#include <stddef.h>
#include <stdint.h>

#include "hil_target_core.h"
#include "loop.h"
#include "link_board.h"
#include "nl_link.h"

static size_t nl_sizeof_period(void) { return sizeof(nl_period_t); }
static size_t nl_sizeof_frame(void) { return sizeof(nl_frame_rec_t); }
static void *nl_slot_periods(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->periods; }
static void *nl_slot_frames(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->frames; }
static int64_t *nl_slot_lateness(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->lateness_ns; }
static nl_finding_t *nl_slot_findings(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->findings; }
static double *nl_slot_noise(nl_handle_t *h, int32_t i) { return nl_slot(h, i)->noise; }

/* The callback link's Python functions (nl_link.h nl_send_fn, nl_recv_fn, nl_diag_fn, nl_period_fn). */
static int nl_py_send(void *ctx, const hil_core_frame_t *f);
static int nl_py_recv(void *ctx, hil_core_frame_t *f, int64_t deadline_ns);
static int nl_py_diag(void *ctx, uint32_t *split_ns, double *torque_ref, uint8_t *full_miss);
static void nl_py_period(void *ctx, double t_s);
/* The board link's period (link_board.h nl_board_period_fn): src/pmsm_hil/hil/runner/board_native_link.py. */
static int nl_py_board_period(void *ctx, const nl_board_meas_t *m, nl_board_cmd_t *cmd);

/* *l: the callback link on ctx (a cffi handle of the Python link); diag and period only when asked for. */
static void nl_py_link(nl_link_t *l, void *ctx, int with_diag, int with_period)
{
    l->send = nl_py_send;
    l->recv = nl_py_recv;
    l->ctx = ctx;
    l->diag = with_diag ? nl_py_diag : NULL;
    l->period = with_period ? nl_py_period : NULL;
    l->flags = 0u;
}

/* *l: the virtual board's link on *s for the Python board link ctx (its callback link without diag and period);
 * the caller sets the scales. */
static void nl_py_board_link(nl_link_t *l, nl_board_link_t *s, void *ctx)
{
    nl_py_link(&s->py, ctx, 0, 0);
    s->period = nl_py_board_period;
    s->ctx = ctx;
    s->py_pending = 1;
    s->q_head = 0;
    s->q_n = 0;
    nl_board_link(l, s);
}

#endif
