/* The portable HIL target core (hil_target_core.h): protocol endpoint around the firmware API. */
#include <stddef.h>
#include <string.h>

#include "hil_app_params.h"
#include "hil_ids.h"
#include "hil_protocol.h"
#include "hil_target_core.h"

/* DBC scales as exact doubles (hex literals: -fsingle-precision-constant does not round them to float),
 * so the decoded values equal the Python codec's raw * scale bit for bit after the float conversion. */
#define SCALE_I3 ((double)0x1.0624dd2f1a9fcp-10L)  /* 0.001 A */
#define SCALE_I6 ((double)0x1.47ae147ae147bp-7L)   /* 0.01 A */
#define SCALE_W ((double)0x1.47ae147ae147bp-6L)    /* 0.02 rad/s */
#define SCALE_V ((double)0x1.47ae147ae147bp-7L)    /* 0.01 V */
#define SCALE_TH ((double)0x1.921fb54442d18p-14L)  /* 2*pi/65536 rad */
#define NS_PER_S ((double)0x1.dcd65p+29L)          /* 1e9 */

/* Duty wire codes (hil.dbc CmdDuty*; src/pmsm_hil/hil/runner/c/pwm_duty.h, src/pmsm_hil/hil/pwm.py) */
#define HIL_CORE_DUTY_FULL 65520u
#define HIL_CORE_DUTY_OUT_OF_RANGE 65534u
#define HIL_CORE_DUTY_NAN 65535u

#define PART_A 1u
#define PART_B 2u
#define PART_C 4u

typedef struct {
    uint8_t have;      /* PART_* bits held */
    uint16_t seq;      /* seq of parts A / C */
    uint8_t seq_lo;    /* seq_lo of part B */
    int16_t i[6];
    uint16_t theta_e;
    int16_t omega_m;
    uint16_t vdc;
    uint8_t status;
} pending_meas_t;

static struct {
    uint8_t enabled;
    uint8_t controller_id;
    uint32_t ts_ns;
    uint64_t k;
    hil_core_counters_t counters;
    hil_core_frame_t txq[HIL_CORE_TX_QUEUE];
    uint8_t tx_head;
    uint8_t tx_count;
    pending_meas_t pend3;
    pending_meas_t pend6;
    hil_app_cmd_t last_cmd;
    uint32_t last_exec_ns;
    uint8_t beats; /* HeartbeatTarget frames sent on its own: the counter of the next one (wraps) */
} g;

#if defined(__GNUC__)
#define HIL_NOINLINE __attribute__((noinline, used))
#else
#define HIL_NOINLINE
#endif

/* Interrupts are masked between the markers on the MCU: a handler that ran inside them (a UART byte or a
 * timer, whose arrival in the emulator follows the host's scheduling) would add its instructions to that one
 * record -- and when it hit the boot pair, whose count is subtracted from every step, to all of them. */
#if defined(__arm__) && defined(__GNUC__)
#define HIL_CORE_IRQ_OFF() __asm__ volatile("cpsid i" ::: "memory")
#define HIL_CORE_IRQ_ON() __asm__ volatile("cpsie i" ::: "memory")
#else
#define HIL_CORE_IRQ_OFF() ((void)0)
#define HIL_CORE_IRQ_ON() ((void)0)
#endif

HIL_NOINLINE void hil_core_step_begin(void)
{
#if defined(__GNUC__)
    __asm__ volatile("" ::: "memory");
#endif
}

HIL_NOINLINE void hil_core_step_end(void)
{
#if defined(__GNUC__)
    __asm__ volatile("" ::: "memory");
#endif
}

static hil_core_frame_t *tx_slot(uint32_t id, uint8_t len, uint8_t fd)
{
    hil_core_frame_t *f;
    if (g.tx_count >= HIL_CORE_TX_QUEUE) {
        g.counters.tx_overflow++;
        return NULL;
    }
    f = &g.txq[(uint8_t)((g.tx_head + g.tx_count) % HIL_CORE_TX_QUEUE)];
    g.tx_count++;
    f->id = id;
    f->len = len;
    f->fd = fd;
    memset(f->data, 0, sizeof f->data);
    return f;
}

static void send_fault(uint8_t code, uint32_t detail)
{
    struct hil_protocol_fault_target_t ft;
    hil_core_frame_t *f = tx_slot(HIL_PROTOCOL_FAULT_TARGET_FRAME_ID, HIL_PROTOCOL_FAULT_TARGET_LENGTH, 0u);
    g.counters.faults++;
    if (f == NULL) {
        return;
    }
    ft.node = HIL_CORE_NODE;
    ft.code = code;
    ft.detail = detail;
    (void)hil_protocol_fault_target_pack(f->data, &ft, HIL_PROTOCOL_FAULT_TARGET_LENGTH);
}

/* Wire code of a duty (hil.dbc CmdDuty*: u16 x 1/65520): NaN 65535, outside 0..1 65534 (DUT findings at
 * the host, never clamped here), else round(d * 65520) half up, computed in double where d * 65520 is exact
 * (24 x 16 bits), so every sender (src/pmsm_hil/protocol/codec_duty.py duty_raw) gives the same code. */
static uint16_t duty_raw(float d)
{
    if (d != d) {
        return HIL_CORE_DUTY_NAN;
    }
    if (!(d >= 0.0f && d <= 1.0f)) {
        return HIL_CORE_DUTY_OUT_OF_RANGE;
    }
    return (uint16_t)((double)d * (double)HIL_CORE_DUTY_FULL + (double)0.5L); /* exact in double: the host's rounding */
}

/* The firmware set both Command forms: duties and a switching sequence (n_states, a duration or mirror). */
static int sets_both_forms(const hil_app_cmd_t *c)
{
    uint8_t j;
    if (c->n_duties == 0u) {
        return 0;
    }
    if (c->n_states != 0u || c->mirror != 0u) {
        return 1;
    }
    for (j = 0u; j < HIL_APP_MAX_STATES; ++j) {
        if (c->durations_ns[j] != 0u) {
            return 1;
        }
    }
    return 0;
}

/* The duty-cycle Command: CmdDutyFd, or CmdDutyA + CmdDutyB + CmdDutyC (legs 3-5 zero for three phases).
 * A firmware that set both forms is reported, never resolved here: n_duties 0 on the wire (the host's rule
 * `duty`, "both forms set"), its duties sent as they are. */
static void send_duty_command(uint16_t seq, const hil_app_cmd_t *c, uint32_t exec_ns, uint8_t fd)
{
    uint16_t r[HIL_APP_MAX_PHASES] = {0u, 0u, 0u, 0u, 0u, 0u};
    const uint8_t n_duties = sets_both_forms(c) ? 0u : c->n_duties;
    hil_core_frame_t *f;
    uint8_t j;
    for (j = 0u; j < c->n_duties && j < HIL_APP_MAX_PHASES; ++j) {
        r[j] = duty_raw(c->duty[j]);
    }
    if (fd) {
        struct hil_protocol_cmd_duty_fd_t cf;
        memset(&cf, 0, sizeof cf);
        cf.seq = seq;
        cf.n_duties = n_duties;
        cf.duty0 = r[0];
        cf.duty1 = r[1];
        cf.duty2 = r[2];
        cf.duty3 = r[3];
        cf.duty4 = r[4];
        cf.duty5 = r[5];
        cf.vector_id = c->vector_id;
        cf.candidates = c->candidates;
        cf.exec_time_ns = exec_ns;
        cf.status = c->status;
        f = tx_slot(HIL_PROTOCOL_CMD_DUTY_FD_FRAME_ID, HIL_PROTOCOL_CMD_DUTY_FD_LENGTH, 1u);
        if (f != NULL) {
            (void)hil_protocol_cmd_duty_fd_pack(f->data, &cf, HIL_PROTOCOL_CMD_DUTY_FD_LENGTH);
        }
    } else {
        struct hil_protocol_cmd_duty_a_t da;
        struct hil_protocol_cmd_duty_b_t db;
        struct hil_protocol_cmd_duty_c_t dc;
        da.seq = seq;
        da.duty0 = r[0];
        da.duty1 = r[1];
        da.duty2 = r[2];
        db.seq = seq;
        db.duty3 = r[3];
        db.duty4 = r[4];
        db.duty5 = r[5];
        dc.seq = seq;
        dc.exec_time_ns = exec_ns;
        dc.status = c->status;
        dc.n_duties = n_duties;
        f = tx_slot(HIL_PROTOCOL_CMD_DUTY_A_FRAME_ID, HIL_PROTOCOL_CMD_DUTY_A_LENGTH, 0u);
        if (f != NULL) {
            (void)hil_protocol_cmd_duty_a_pack(f->data, &da, HIL_PROTOCOL_CMD_DUTY_A_LENGTH);
        }
        f = tx_slot(HIL_PROTOCOL_CMD_DUTY_B_FRAME_ID, HIL_PROTOCOL_CMD_DUTY_B_LENGTH, 0u);
        if (f != NULL) {
            (void)hil_protocol_cmd_duty_b_pack(f->data, &db, HIL_PROTOCOL_CMD_DUTY_B_LENGTH);
        }
        f = tx_slot(HIL_PROTOCOL_CMD_DUTY_C_FRAME_ID, HIL_PROTOCOL_CMD_DUTY_C_LENGTH, 0u);
        if (f != NULL) {
            (void)hil_protocol_cmd_duty_c_pack(f->data, &dc, HIL_PROTOCOL_CMD_DUTY_C_LENGTH);
        }
    }
}

static void send_command(uint16_t seq, const hil_app_cmd_t *c, uint32_t exec_ns, uint8_t fd)
{
    hil_core_frame_t *f;
    g.counters.commands++;
    if (c->n_duties != 0u) {
        send_duty_command(seq, c, exec_ns, fd);
        return;
    }
    if (fd) {
        struct hil_protocol_cmd_fd_t cf;
        memset(&cf, 0, sizeof cf);
        cf.seq = seq;
        cf.state0 = c->states[0];
        cf.state1 = c->states[1];
        cf.state2 = c->states[2];
        cf.n_states = c->n_states;
        cf.duration0 = c->durations_ns[0];
        cf.duration1 = c->durations_ns[1];
        cf.duration2 = c->durations_ns[2];
        cf.vector_id = c->vector_id;
        cf.candidates = c->candidates;
        cf.exec_time_ns = exec_ns;
        cf.status = c->status;
        cf.mirror = c->mirror ? 1u : 0u;
        f = tx_slot(HIL_PROTOCOL_CMD_FD_FRAME_ID, HIL_PROTOCOL_CMD_FD_LENGTH, 1u);
        if (f != NULL) {
            (void)hil_protocol_cmd_fd_pack(f->data, &cf, HIL_PROTOCOL_CMD_FD_LENGTH);
        }
    } else {
        struct hil_protocol_cmd_a_t ca;
        struct hil_protocol_cmd_b_t cb;
        struct hil_protocol_cmd_c_t cc;
        ca.seq = seq;
        ca.state0 = c->states[0];
        ca.state1 = c->states[1];
        ca.state2 = c->states[2];
        ca.n_states = c->n_states;
        ca.duration0 = c->durations_ns[0];
        ca.vector_id = c->vector_id;
        cb.seq = seq;
        cb.duration1 = c->durations_ns[1];
        cb.duration2 = c->durations_ns[2];
        cb.candidates = c->candidates;
        cc.seq = seq;
        cc.exec_time_ns = exec_ns;
        cc.status = c->status;
        cc.mirror = c->mirror ? 1u : 0u;
        f = tx_slot(HIL_PROTOCOL_CMD_A_FRAME_ID, HIL_PROTOCOL_CMD_A_LENGTH, 0u);
        if (f != NULL) {
            (void)hil_protocol_cmd_a_pack(f->data, &ca, HIL_PROTOCOL_CMD_A_LENGTH);
        }
        f = tx_slot(HIL_PROTOCOL_CMD_B_FRAME_ID, HIL_PROTOCOL_CMD_B_LENGTH, 0u);
        if (f != NULL) {
            (void)hil_protocol_cmd_b_pack(f->data, &cb, HIL_PROTOCOL_CMD_B_LENGTH);
        }
        f = tx_slot(HIL_PROTOCOL_CMD_C_FRAME_ID, HIL_PROTOCOL_CMD_C_LENGTH, 0u);
        if (f != NULL) {
            (void)hil_protocol_cmd_c_pack(f->data, &cc, HIL_PROTOCOL_CMD_C_LENGTH);
        }
    }
}

/* Measurement k: disabled -> full-period zero vector (state 0); enabled -> the firmware's step. */
static void on_measurement(const pending_meas_t *p, uint8_t n_phases, double scale_i, uint8_t fd)
{
    hil_app_cmd_t cmd;
    uint32_t exec_ns = 0u;
    uint8_t j;
    const uint64_t t_ns = g.k * (uint64_t)g.ts_ns;
    g.k++;
    g.counters.measurements++;
    memset(&cmd, 0, sizeof cmd);
    if (!g.enabled) {
        cmd.n_states = 1u;
        cmd.durations_ns[0] = g.ts_ns;
    } else {
        hil_app_meas_t m;
        uint32_t t0;
        uint32_t t1;
        memset(&m, 0, sizeof m);
        m.t_ns = t_ns;
        m.seq = p->seq;
        m.n_phases = n_phases;
        m.status = p->status;
        for (j = 0u; j < n_phases; ++j) {
            m.i[j] = (float)((double)p->i[j] * scale_i);
        }
        m.theta_e = (float)((double)p->theta_e * SCALE_TH);
        m.omega_m = (float)((double)p->omega_m * SCALE_W);
        m.vdc = (float)((double)p->vdc * SCALE_V);
        t0 = hil_board_clock();
        HIL_CORE_IRQ_OFF();
        hil_core_step_begin();
        hil_app_step(&m, &cmd);
        hil_core_step_end();
        HIL_CORE_IRQ_ON();
        t1 = hil_board_clock();
        exec_ns = hil_board_exec_ns(t0, t1);
        g.counters.steps++;
        g.last_cmd = cmd;
        g.last_exec_ns = exec_ns;
    }
    send_command(p->seq, &cmd, exec_ns, fd);
}

/* 0 for a ts the Commands cannot carry (a sub-interval longer than the duration field, not positive, NaN):
 * rejected before the firmware sees it; 1 for any other parameter. Never casts a NaN. */
static int ts_fits(const struct hil_protocol_config_param_t *cp)
{
    double ns;
    if (cp->param_id != HIL_FW_P_TS) {
        return 1;
    }
    ns = (double)cp->value * NS_PER_S;
    if (!(ns > 0 && ns < (double)0xFFFFFFFFL)) {
        return 0;
    }
    return hil_protocol_cmd_a_duration0_is_in_range((uint32_t)(ns + (double)0.5L)) ? 1 : 0;
}

/* Firmware parameters (hil_app_params.h): weak, so a firmware that declares none links (addresses 0). */
extern const hil_app_param_t hil_app_params[] __attribute__((weak));
extern const uint32_t hil_app_params_count __attribute__((weak));

/* 0 for a value outside the [min, max] (or NaN) of a parameter the firmware declared in its table; 1 otherwise
 * (ids the table does not name go to hil_app_config as they are). */
static int in_declared_range(const struct hil_protocol_config_param_t *cp)
{
    uint32_t i;
    if (cp->param_id < HIL_APP_PARAM_ID_FIRST || &hil_app_params_count == NULL || hil_app_params == NULL) {
        return 1;
    }
    for (i = 0u; i < hil_app_params_count; ++i) {
        if (hil_app_params[i].id == cp->param_id) {
            return cp->value >= hil_app_params[i].min && cp->value <= hil_app_params[i].max;
        }
    }
    return 1;
}

static void on_config(const uint8_t *data)
{
    struct hil_protocol_config_param_t cp;
    struct hil_protocol_config_ack_t ack;
    hil_core_frame_t *f;
    (void)hil_protocol_config_param_unpack(&cp, data, HIL_PROTOCOL_CONFIG_PARAM_LENGTH);
    g.counters.config_writes++;
    ack.param_id = cp.param_id;
    ack.value = cp.value; /* echoed bit for bit, NaN included (a float copy, no arithmetic) */
    if (ts_fits(&cp) && in_declared_range(&cp) && hil_app_config(cp.param_id, cp.value) == HIL_APP_OK) {
        ack.status = HIL_FW_STATUS_OK;
        if (cp.param_id == HIL_FW_P_TS) {
            const double ns = (double)cp.value * NS_PER_S;
            g.ts_ns = (uint32_t)(ns + (double)0.5L); /* in range: checked by ts_fits */
        }
    } else {
        g.counters.config_rejected++;
        ack.status = HIL_FW_STATUS_INVALID_CONFIG;
    }
    f = tx_slot(HIL_PROTOCOL_CONFIG_ACK_FRAME_ID, HIL_PROTOCOL_CONFIG_ACK_LENGTH, 0u);
    if (f != NULL) {
        (void)hil_protocol_config_ack_pack(f->data, &ack, HIL_PROTOCOL_CONFIG_ACK_LENGTH);
    }
}

static void send_heartbeat(uint8_t state, uint8_t counter)
{
    struct hil_protocol_heartbeat_target_t out;
    hil_core_frame_t *f = tx_slot(HIL_PROTOCOL_HEARTBEAT_TARGET_FRAME_ID, HIL_PROTOCOL_HEARTBEAT_TARGET_LENGTH, 0u);
    if (f == NULL) {
        return;
    }
    out.node = HIL_CORE_NODE;
    out.state = state;
    out.counter = counter;
    (void)hil_protocol_heartbeat_target_pack(f->data, &out, HIL_PROTOCOL_HEARTBEAT_TARGET_LENGTH);
}

static void apply_setpoint(const struct hil_protocol_setpoint_t *sp)
{
    const uint8_t was = g.enabled;
    const uint8_t enable = sp->enable != 0u ? 1u : 0u;
    if (sp->controller_id != g.controller_id) {
        if (hil_app_select(sp->controller_id) != HIL_APP_OK) {
            g.enabled = 0u;
            send_fault(HIL_FW_STATUS_NOT_IMPLEMENTED, sp->controller_id);
            return;
        }
        g.controller_id = sp->controller_id;
    }
    if (enable && !was) {
        hil_app_reset();
    }
    if (hil_app_setpoint(enable, sp->mode, sp->reference) != HIL_APP_OK) {
        g.enabled = 0u;
        send_fault(HIL_FW_STATUS_INVALID_CONFIG, sp->mode);
        return;
    }
    g.enabled = enable;
}

/* The confirmed safe stop (docs/runner.md): every disabling Setpoint is answered with HeartbeatTarget idle,
 * after the core is disabled, whatever else the Setpoint caused (a Fault for an unknown controller id). */
static void on_setpoint(const uint8_t *data)
{
    struct hil_protocol_setpoint_t sp;
    (void)hil_protocol_setpoint_unpack(&sp, data, HIL_PROTOCOL_SETPOINT_LENGTH);
    apply_setpoint(&sp);
    if (sp.enable == 0u) {
        send_heartbeat(HIL_PROTOCOL_HEARTBEAT_TARGET_STATE_IDLE_CHOICE, g.beats);
        g.beats++;
    }
}

static void on_heartbeat(const uint8_t *data)
{
    struct hil_protocol_heartbeat_host_t hb;
    (void)hil_protocol_heartbeat_host_unpack(&hb, data, HIL_PROTOCOL_HEARTBEAT_HOST_LENGTH);
    if (hb.node == HIL_CORE_NODE) {
        return;
    }
    send_heartbeat(g.enabled ? HIL_PROTOCOL_HEARTBEAT_TARGET_STATE_RUNNING_CHOICE
                             : HIL_PROTOCOL_HEARTBEAT_TARGET_STATE_IDLE_CHOICE, hb.counter);
}

/* Classic frames: a measurement is complete when its parts carry one seq (B only its low byte). */
static void try_complete(pending_meas_t *p, uint8_t need, uint8_t n_phases, double scale_i)
{
    if ((p->have & need) == need && p->seq_lo == (uint8_t)(p->seq & 0xFFu)) {
        p->have = 0u;
        on_measurement(p, n_phases, scale_i, 0u);
    }
}

/* A CAN FD measurement (MeasFd, MeasFd6): the n_phases currents of `i` and the rest, whole in one frame. */
static void on_fd_measurement(uint16_t seq, const int16_t *i, uint8_t n_phases, uint16_t theta_e, int16_t omega_m,
                              uint16_t vdc, uint8_t status)
{
    pending_meas_t p;
    memset(&p, 0, sizeof p);
    p.seq = seq;
    memcpy(p.i, i, n_phases * sizeof i[0]);
    p.theta_e = theta_e;
    p.omega_m = omega_m;
    p.vdc = vdc;
    p.status = status;
    on_measurement(&p, n_phases, n_phases == 6u ? SCALE_I6 : SCALE_I3, 1u);
}

static uint8_t expected_length(uint32_t id)
{
    switch (id) {
    case HIL_PROTOCOL_MEAS_FD_FRAME_ID: return HIL_PROTOCOL_MEAS_FD_LENGTH;
    case HIL_PROTOCOL_MEAS_FD6_FRAME_ID: return HIL_PROTOCOL_MEAS_FD6_LENGTH;
    case HIL_PROTOCOL_MEAS_A_FRAME_ID: return HIL_PROTOCOL_MEAS_A_LENGTH;
    case HIL_PROTOCOL_MEAS_B_FRAME_ID: return HIL_PROTOCOL_MEAS_B_LENGTH;
    case HIL_PROTOCOL_MEAS6_A_FRAME_ID: return HIL_PROTOCOL_MEAS6_A_LENGTH;
    case HIL_PROTOCOL_MEAS6_B_FRAME_ID: return HIL_PROTOCOL_MEAS6_B_LENGTH;
    case HIL_PROTOCOL_MEAS6_C_FRAME_ID: return HIL_PROTOCOL_MEAS6_C_LENGTH;
    case HIL_PROTOCOL_SETPOINT_FRAME_ID: return HIL_PROTOCOL_SETPOINT_LENGTH;
    case HIL_PROTOCOL_CONFIG_PARAM_FRAME_ID: return HIL_PROTOCOL_CONFIG_PARAM_LENGTH;
    case HIL_PROTOCOL_HEARTBEAT_HOST_FRAME_ID: return HIL_PROTOCOL_HEARTBEAT_HOST_LENGTH;
    case HIL_PROTOCOL_HEARTBEAT_TARGET_FRAME_ID: return HIL_PROTOCOL_HEARTBEAT_TARGET_LENGTH;
    case HIL_PROTOCOL_FAULT_HOST_FRAME_ID: return HIL_PROTOCOL_FAULT_HOST_LENGTH;
    default: return 0u;
    }
}

void hil_core_rx(uint32_t id, const uint8_t *data, uint8_t len, uint8_t fd)
{
    const uint8_t want = expected_length(id);
    (void)fd; /* the id tells the layout; like the Python decoder, both profiles are accepted */
    g.counters.frames_rx++;
    if (want == 0u) {
        g.counters.unknown_id++;
        return;
    }
    if (len != want) {
        g.counters.bad_length++;
        return;
    }
    switch (id) {
    case HIL_PROTOCOL_MEAS_FD_FRAME_ID: {
        struct hil_protocol_meas_fd_t m;
        (void)hil_protocol_meas_fd_unpack(&m, data, len);
        const int16_t i[3] = {m.i_a, m.i_b, m.i_c};
        on_fd_measurement(m.seq, i, 3u, m.theta_e, m.omega_m, m.vdc, m.status);
        break;
    }
    case HIL_PROTOCOL_MEAS_FD6_FRAME_ID: {
        struct hil_protocol_meas_fd6_t m;
        (void)hil_protocol_meas_fd6_unpack(&m, data, len);
        const int16_t i[6] = {m.i_a, m.i_b, m.i_c, m.i_u, m.i_v, m.i_w};
        on_fd_measurement(m.seq, i, 6u, m.theta_e, m.omega_m, m.vdc, m.status);
        break;
    }
    case HIL_PROTOCOL_MEAS_A_FRAME_ID: {
        struct hil_protocol_meas_a_t m;
        (void)hil_protocol_meas_a_unpack(&m, data, len);
        if ((g.pend3.have & PART_A) && g.pend3.seq != m.seq) {
            g.pend3.have = 0u; /* a newer measurement: drop the incomplete one */
        }
        g.pend3.seq = m.seq;
        g.pend3.i[0] = m.i_a;
        g.pend3.i[1] = m.i_b;
        g.pend3.i[2] = m.i_c;
        g.pend3.have |= PART_A;
        if ((g.pend3.have & PART_B) && g.pend3.seq_lo != (uint8_t)(m.seq & 0xFFu)) {
            g.pend3.have &= (uint8_t)~PART_B;
        }
        try_complete(&g.pend3, PART_A | PART_B, 3u, SCALE_I3);
        break;
    }
    case HIL_PROTOCOL_MEAS_B_FRAME_ID:
    case HIL_PROTOCOL_MEAS6_B_FRAME_ID: {
        struct hil_protocol_meas_b_t m;
        const int six = id == HIL_PROTOCOL_MEAS6_B_FRAME_ID;
        pending_meas_t *p = six ? &g.pend6 : &g.pend3;
        (void)hil_protocol_meas_b_unpack(&m, data, len); /* Meas6B has MeasB's layout */
        p->seq_lo = m.seq_lo;
        p->theta_e = m.theta_e;
        p->omega_m = m.omega_m;
        p->vdc = m.vdc;
        p->status = m.status;
        p->have |= PART_B;
        if (six) {
            try_complete(p, PART_A | PART_B | PART_C, 6u, SCALE_I6);
        } else {
            try_complete(p, PART_A | PART_B, 3u, SCALE_I3);
        }
        break;
    }
    case HIL_PROTOCOL_MEAS6_A_FRAME_ID:
    case HIL_PROTOCOL_MEAS6_C_FRAME_ID: {
        struct hil_protocol_meas6_a_t m; /* Meas6C has Meas6A's layout (i_u, i_v, i_w) */
        const uint8_t part = id == HIL_PROTOCOL_MEAS6_A_FRAME_ID ? PART_A : PART_C;
        const uint8_t off = part == PART_A ? 0u : 3u;
        (void)hil_protocol_meas6_a_unpack(&m, data, len);
        if ((g.pend6.have & (PART_A | PART_C)) && g.pend6.seq != m.seq) {
            g.pend6.have = 0u;
        }
        g.pend6.seq = m.seq;
        g.pend6.i[off] = m.i_a;
        g.pend6.i[off + 1u] = m.i_b;
        g.pend6.i[off + 2u] = m.i_c;
        g.pend6.have |= part;
        try_complete(&g.pend6, PART_A | PART_B | PART_C, 6u, SCALE_I6);
        break;
    }
    case HIL_PROTOCOL_SETPOINT_FRAME_ID:
        on_setpoint(data);
        break;
    case HIL_PROTOCOL_CONFIG_PARAM_FRAME_ID:
        on_config(data);
        break;
    case HIL_PROTOCOL_HEARTBEAT_HOST_FRAME_ID:
    case HIL_PROTOCOL_HEARTBEAT_TARGET_FRAME_ID:
        on_heartbeat(data);
        break;
    default: /* FaultHost: informational */
        break;
    }
}

int hil_core_tx(hil_core_frame_t *out)
{
    if (g.tx_count == 0u) {
        return 0;
    }
    *out = g.txq[g.tx_head];
    g.tx_head = (uint8_t)((g.tx_head + 1u) % HIL_CORE_TX_QUEUE);
    g.tx_count--;
    return 1;
}

void hil_core_init(void)
{
    memset(&g, 0, sizeof g);
    g.ts_ns = 100000u;
    g.controller_id = HIL_FW_CTRL_OFF;
    hil_app_init();
    HIL_CORE_IRQ_OFF();
    hil_core_step_begin(); /* the markers' own cost, for an instruction counter to subtract */
    hil_core_step_end();
    HIL_CORE_IRQ_ON();
}

const hil_core_counters_t *hil_core_counters(void)
{
    return &g.counters;
}

const hil_app_cmd_t *hil_core_last_cmd(void)
{
    return &g.last_cmd;
}

uint32_t hil_core_last_exec_ns(void)
{
    return g.last_exec_ns;
}
