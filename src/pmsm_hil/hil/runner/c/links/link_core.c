/* The in-process link to the C target core (link_core.h). */

#include "link_core.h"

/* The reference firmware's profiled step (hil_app_reference.c built with HIL_APP_REFERENCE_PROFILED): the
 * stage split [ns] and the restricted-vs-full candidate diagnostic of the last step. */
void hil_app_reference_diag(uint32_t split_ns[3], uint8_t *full_miss);

/* Measurement frame ids: 0x100..0x10F (hil.dbc; MeasA/B, Meas6A/B/C, MeasFd, MeasFd6). */
#define MEAS_ID_FIRST 0x100u
#define MEAS_ID_LAST 0x10Fu

int nl_core_send(nl_core_link_t *s, const hil_core_frame_t *f)
{
    const int silent = s->silent_after >= 0 && s->measurements > s->silent_after;
    s->stats.frames_tx++;
    if (!silent || f->id < MEAS_ID_FIRST || f->id > MEAS_ID_LAST) {
        hil_core_rx(f->id, f->data, f->len, f->fd);
    }
    return 0;
}

int nl_core_recv(nl_core_link_t *s, hil_core_frame_t *f, int64_t deadline_ns)
{
    (void)deadline_ns;
    if (!hil_core_tx(f)) {
        return 0;
    }
    s->stats.frames_rx++;
    return 1;
}

/* The step behind the last reply: nothing before the firmware's first step. */
static int core_diag(void *ctx, uint32_t *split_ns, double *torque_ref, uint8_t *full_miss)
{
    (void)ctx;
    if (hil_core_counters()->steps == 0u) {
        return 0;
    }
    hil_app_reference_diag(split_ns, full_miss);
    *torque_ref = (double)hil_core_last_cmd()->torque_ref;
    return 1;
}

static void core_period(void *ctx, double t_s)
{
    (void)t_s;
    ((nl_core_link_t *)ctx)->measurements++;
}

static int core_send_any(void *ctx, const hil_core_frame_t *f)
{
    return nl_core_send((nl_core_link_t *)ctx, f);
}

static int core_recv_any(void *ctx, hil_core_frame_t *f, int64_t deadline_ns)
{
    return nl_core_recv((nl_core_link_t *)ctx, f, deadline_ns);
}

void nl_core_link(nl_link_t *l, nl_core_link_t *s)
{
    l->send = core_send_any;
    l->recv = core_recv_any;
    l->ctx = s;
    l->diag = core_diag;
    l->period = core_period;
    l->flags = NL_LINK_IN_PROCESS;
}
