/* The native loop's link to the virtual STM32G4 board (link_board.h). */

#include <math.h>
#include <string.h>

#include "hil_protocol.h"
#include "link_board.h"

/* codec_duty.py duty_raw: 0..1 -> floor(d * 65520 + 0.5), NaN -> 65535, outside 0..1 -> 65534. */
static uint16_t duty_raw(double d)
{
    if (isnan(d)) {
        return 65535u;
    }
    if (!(d >= 0.0 && d <= 1.0)) {
        return 65534u;
    }
    return (uint16_t)floor(d * 65520.0 + 0.5);
}

static void queue_command(nl_board_link_t *s, uint16_t seq, const nl_board_cmd_t *cmd)
{
    struct hil_protocol_cmd_duty_fd_t c;
    hil_core_frame_t *f;
    const int64_t ex = cmd->exec_time_ns;
    if (s->q_n >= NL_BOARD_QUEUE) { /* never: the loop drains each reply before the next Measurement */
        return;
    }
    f = &s->q[(s->q_head + s->q_n) % NL_BOARD_QUEUE];
    memset(&c, 0, sizeof c);
    c.seq = seq;
    c.n_duties = 3u;
    c.duty0 = duty_raw(cmd->duties[0]);
    c.duty1 = duty_raw(cmd->duties[1]);
    c.duty2 = duty_raw(cmd->duties[2]);
    c.exec_time_ns = ex < 0 ? 0u : ex > (int64_t)UINT32_MAX ? UINT32_MAX : (uint32_t)ex;
    memset(f, 0, sizeof *f);
    f->id = HIL_PROTOCOL_CMD_DUTY_FD_FRAME_ID;
    f->len = HIL_PROTOCOL_CMD_DUTY_FD_LENGTH;
    f->fd = 1u;
    (void)hil_protocol_cmd_duty_fd_pack(f->data, &c, HIL_PROTOCOL_CMD_DUTY_FD_LENGTH);
    s->q_n++;
}

int nl_board_send(nl_board_link_t *s, const hil_core_frame_t *f)
{
    struct hil_protocol_meas_fd_t raw;
    nl_board_meas_t m;
    nl_board_cmd_t cmd;
    if (f->id != HIL_PROTOCOL_MEAS_FD_FRAME_ID || f->len != HIL_PROTOCOL_MEAS_FD_LENGTH) {
        return s->py.send(s->py.ctx, f);
    }
    (void)hil_protocol_meas_fd_unpack(&raw, f->data, f->len);
    m.seq = raw.seq;
    m.status = raw.status;
    m.i_a = (double)raw.i_a * s->scale_i;
    m.i_b = (double)raw.i_b * s->scale_i;
    m.i_c = (double)raw.i_c * s->scale_i;
    m.theta_e = (double)raw.theta_e * s->scale_theta;
    m.omega_m = (double)raw.omega_m * s->scale_omega;
    m.vdc = (double)raw.vdc * s->scale_vdc;
    memset(&cmd, 0, sizeof cmd);
    s->stats.frames_tx++;
    if (s->inputs) {
        const double values[4] = {m.i_a, m.i_b, m.i_c, m.vdc};
        s->inputs(s->inputs_user, values);
    }
    if (s->fast && s->outputs && !s->py_pending) {
        const double values[6] = {m.i_a, m.i_b, m.i_c, m.theta_e, m.omega_m, m.vdc};
        if (s->fast(s->fast_user, values, &cmd.exec_time_ns)) {
            cmd.form = NL_BOARD_OUTPUTS;
        }
    }
    if (cmd.form != NL_BOARD_OUTPUTS && s->period(s->ctx, &m, &cmd) != 0) {
        return -1;
    }
    if (cmd.form == NL_BOARD_OUTPUTS) { /* the board answered only after checking that `outputs` has duties */
        const double currents[3] = {m.i_a, m.i_b, m.i_c};
        if (!s->outputs || !s->outputs(s->outputs_user, currents, cmd.duties)) {
            return -1;
        }
        cmd.form = NL_BOARD_DUTIES;
    }
    if (cmd.form == NL_BOARD_DUTIES) {
        queue_command(s, raw.seq, &cmd);
    }
    return 0;
}

int nl_board_recv(nl_board_link_t *s, hil_core_frame_t *f, int64_t deadline_ns)
{
    if (s->q_n > 0) {
        *f = s->q[s->q_head];
        s->q_head = (s->q_head + 1) % NL_BOARD_QUEUE;
        s->q_n--;
        s->stats.frames_rx++;
        return 1;
    }
    if (!s->py_pending) {
        return 0;
    }
    return s->py.recv(s->py.ctx, f, deadline_ns);
}

NL_LINK_DEFINE(nl_board, nl_board_link_t)
