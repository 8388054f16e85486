/* Host side of the frame protocol for the native loop (loop_frames.h). */
#include <math.h>
#include <string.h>

#include "hil_ids.h"
#include "hil_protocol.h"
#include "loop_frames.h"

#define PART_A 1u
#define PART_B 2u
#define PART_C 4u

/* round(x / scale) of Python, saturated to [lo, hi] (src/pmsm_hil/protocol/codec.py FrameCodec._sat); -1 if x is NaN. */
static int sat_raw(double x, double scale, int32_t lo, int32_t hi, int32_t *raw)
{
    double r;
    if (isnan(x)) {
        return -1;
    }
    r = nearbyint(x / scale); /* default rounding: to nearest, ties to even (Python round) */
    if (!(r >= (double)lo)) {
        *raw = lo; /* also -inf */
    } else if (!(r <= (double)hi)) {
        *raw = hi;
    } else {
        *raw = (int32_t)r;
    }
    return 0;
}

/* round(theta / scale) % mod of Python; -1 if not finite. */
static int wrap_raw(double theta, double scale, int32_t mod, int32_t *raw)
{
    double r;
    if (!isfinite(theta)) {
        return -1;
    }
    r = fmod(nearbyint(theta / scale), (double)mod);
    if (r < 0.0) {
        r += (double)mod;
    }
    *raw = (int32_t)r;
    return 0;
}

static void frame_init(hil_core_frame_t *f, uint32_t id, uint8_t len, uint8_t fd)
{
    f->id = id;
    f->len = len;
    f->fd = fd;
    memset(f->data, 0, sizeof f->data);
}

int nl_encode_meas(const nl_config_t *c, uint16_t seq, const double *currents, double theta_e, double omega_m,
                   hil_core_frame_t *out, int *n, int32_t *bad_field, double *bad_value)
{
    int32_t i[6] = {0, 0, 0, 0, 0, 0};
    int32_t th, w, v;
    const int legs = c->machine.legs;
    const nl_codec_cfg_t *codec = &c->target_link.codec;
    int j;
    if (wrap_raw(theta_e, codec->s_th, codec->th_mod, &th) != 0) {
        *bad_field = 0;
        *bad_value = theta_e;
        return -1;
    }
    for (j = 0; j < legs; ++j) {
        if (sat_raw(currents[j], codec->s_i, codec->i_min, codec->i_max, &i[j]) != 0) {
            *bad_field = 1 + j;
            *bad_value = currents[j];
            return -1;
        }
    }
    if (sat_raw(omega_m, codec->s_w, codec->w_min, codec->w_max, &w) != 0) {
        *bad_field = legs + 1;
        *bad_value = omega_m;
        return -1;
    }
    if (sat_raw(c->machine.vdc, codec->s_v, codec->v_min, codec->v_max, &v) != 0) {
        *bad_field = legs + 2;
        *bad_value = c->machine.vdc;
        return -1;
    }
    if (codec->meas_format == NL_MEAS_3 && codec->fd) {
        struct hil_protocol_meas_fd_t m;
        m.seq = seq;
        m.i_a = (int16_t)i[0];
        m.i_b = (int16_t)i[1];
        m.i_c = (int16_t)i[2];
        m.theta_e = (uint16_t)th;
        m.omega_m = (int16_t)w;
        m.vdc = (uint16_t)v;
        m.status = 0u;
        frame_init(&out[0], HIL_PROTOCOL_MEAS_FD_FRAME_ID, HIL_PROTOCOL_MEAS_FD_LENGTH, 1u);
        (void)hil_protocol_meas_fd_pack(out[0].data, &m, HIL_PROTOCOL_MEAS_FD_LENGTH);
        *n = 1;
    } else if (codec->meas_format == NL_MEAS_6 && codec->fd) {
        struct hil_protocol_meas_fd6_t m;
        m.seq = seq;
        m.i_a = (int16_t)i[0];
        m.i_b = (int16_t)i[1];
        m.i_c = (int16_t)i[2];
        m.i_u = (int16_t)i[3];
        m.i_v = (int16_t)i[4];
        m.i_w = (int16_t)i[5];
        m.theta_e = (uint16_t)th;
        m.omega_m = (int16_t)w;
        m.vdc = (uint16_t)v;
        m.status = 0u;
        frame_init(&out[0], HIL_PROTOCOL_MEAS_FD6_FRAME_ID, HIL_PROTOCOL_MEAS_FD6_LENGTH, 1u);
        (void)hil_protocol_meas_fd6_pack(out[0].data, &m, HIL_PROTOCOL_MEAS_FD6_LENGTH);
        *n = 1;
    } else {
        struct hil_protocol_meas_a_t a; /* Meas6A and Meas6C have this layout */
        struct hil_protocol_meas_b_t b; /* Meas6B too */
        const int six = codec->meas_format == NL_MEAS_6;
        int k = 0;
        a.seq = seq;
        a.i_a = (int16_t)i[0];
        a.i_b = (int16_t)i[1];
        a.i_c = (int16_t)i[2];
        frame_init(&out[k], six ? HIL_PROTOCOL_MEAS6_A_FRAME_ID : HIL_PROTOCOL_MEAS_A_FRAME_ID,
                   HIL_PROTOCOL_MEAS_A_LENGTH, 0u);
        (void)hil_protocol_meas_a_pack(out[k++].data, &a, HIL_PROTOCOL_MEAS_A_LENGTH);
        if (six) {
            a.i_a = (int16_t)i[3];
            a.i_b = (int16_t)i[4];
            a.i_c = (int16_t)i[5];
            frame_init(&out[k], HIL_PROTOCOL_MEAS6_C_FRAME_ID, HIL_PROTOCOL_MEAS_A_LENGTH, 0u);
            (void)hil_protocol_meas_a_pack(out[k++].data, &a, HIL_PROTOCOL_MEAS_A_LENGTH);
        }
        b.seq_lo = (uint8_t)(seq & 0xFFu);
        b.theta_e = (uint16_t)th;
        b.omega_m = (int16_t)w;
        b.vdc = (uint16_t)v;
        b.status = 0u;
        frame_init(&out[k], six ? HIL_PROTOCOL_MEAS6_B_FRAME_ID : HIL_PROTOCOL_MEAS_B_FRAME_ID,
                   HIL_PROTOCOL_MEAS_B_LENGTH, 0u);
        (void)hil_protocol_meas_b_pack(out[k++].data, &b, HIL_PROTOCOL_MEAS_B_LENGTH);
        *n = k;
    }
    return 0;
}

void nl_encode_setpoint(uint8_t enable, uint8_t mode, double reference, uint8_t controller_id,
                        hil_core_frame_t *out)
{
    struct hil_protocol_setpoint_t s;
    s.enable = enable;
    s.mode = mode;
    s.reference = (float)reference;
    s.controller_id = controller_id;
    frame_init(out, HIL_PROTOCOL_SETPOINT_FRAME_ID, HIL_PROTOCOL_SETPOINT_LENGTH, 0u);
    (void)hil_protocol_setpoint_pack(out->data, &s, HIL_PROTOCOL_SETPOINT_LENGTH);
}

/* The length of a frame of hil.dbc, 0 for an id it does not have. */
static uint8_t known_length(uint32_t id)
{
    switch (id) {
#define LENGTH_CASE(frame_id, length, target, command) case frame_id: return length;
    HIL_FRAMES(LENGTH_CASE)
#undef LENGTH_CASE
    default: return 0u;
    }
}

static void asm_clear(nl_asm_held_t *h)
{
    h->have = 0u;
    h->held_seq = -1;
    h->unordered = 0u;
}

/* Assembler.add(part, seq, 0xFFFF) with ordered=False on one Command kind's held parts: 1 when all three parts of
 * one seq are held, -1 for a part already held (counted), else 0. */
static int asm_add(nl_asm_held_t *h, uint8_t part_bit, uint16_t seq, nl_result_t *r)
{
    if (h->held_seq >= 0) {
        if ((uint16_t)h->held_seq == seq) {
            if (h->have & part_bit) {
                r->dec_duplicate++;
                return -1;
            }
        } else {
            r->dec_mixed_seq++;
            asm_clear(h);
        }
    }
    if (h->held_seq < 0) {
        h->held_seq = seq;
    }
    if (!h->unordered && (h->have & (uint8_t)~(uint8_t)((part_bit << 1) - 1u)) != 0u) {
        h->unordered = 1u; /* a later part is already held */
    }
    h->have |= part_bit;
    return h->have == (PART_A | PART_B | PART_C) ? 1 : 0;
}

static int cmd_part(nl_cmd_asm_t *as, const hil_core_frame_t *f, nl_result_t *r, nl_cmd_t *cmd)
{
    int done = 0;
    if (f->id == HIL_PROTOCOL_CMD_A_FRAME_ID) {
        struct hil_protocol_cmd_a_t a;
        (void)hil_protocol_cmd_a_unpack(&a, f->data, f->len);
        if (a.n_states < 1u || a.n_states > 3u) {
            r->dec_bad_value++;
            return NL_MSG_NONE;
        }
        done = asm_add(&as->states, PART_A, a.seq, r);
        if (done < 0) {
            return NL_MSG_NONE;
        }
        as->a_states[0] = a.state0;
        as->a_states[1] = a.state1;
        as->a_states[2] = a.state2;
        as->a_n = a.n_states;
        as->a_d0 = a.duration0;
        as->a_vector_id = a.vector_id;
    } else if (f->id == HIL_PROTOCOL_CMD_B_FRAME_ID) {
        struct hil_protocol_cmd_b_t b;
        (void)hil_protocol_cmd_b_unpack(&b, f->data, f->len);
        done = asm_add(&as->states, PART_B, b.seq, r);
        if (done < 0) {
            return NL_MSG_NONE;
        }
        as->b_d1 = b.duration1;
        as->b_d2 = b.duration2;
        as->b_candidates = b.candidates;
    } else {
        struct hil_protocol_cmd_c_t c;
        (void)hil_protocol_cmd_c_unpack(&c, f->data, f->len);
        done = asm_add(&as->states, PART_C, c.seq, r);
        if (done < 0) {
            return NL_MSG_NONE;
        }
        as->c_exec = c.exec_time_ns;
        as->c_status = c.status;
        as->c_mirror = c.mirror;
    }
    if (!done) {
        return NL_MSG_NONE;
    }
    if (as->states.unordered) {
        r->dec_out_of_order++;
    }
    cmd->seq = (uint16_t)as->states.held_seq;
    cmd->n_states = as->a_n;
    memcpy(cmd->states, as->a_states, sizeof cmd->states);
    cmd->durations_ns[0] = as->a_d0;
    cmd->durations_ns[1] = as->b_d1;
    cmd->durations_ns[2] = as->b_d2;
    cmd->vector_id = as->a_vector_id;
    cmd->candidates = as->b_candidates;
    cmd->exec_time_ns = as->c_exec;
    cmd->status = as->c_status;
    cmd->mirror = as->c_mirror == 1u ? 1u : 0u;
    cmd->n_duties = 0u;
    memset(cmd->duty_raw, 0, sizeof cmd->duty_raw);
    cmd->both_forms = 0u;
    asm_clear(&as->states);
    return NL_MSG_COMMAND;
}

/* A duty-cycle Command's part (CmdDutyA/B/C; codec.py FrameDecoder._duty_part). */
static int duty_part(nl_cmd_asm_t *as, const hil_core_frame_t *f, nl_result_t *r, nl_cmd_t *cmd)
{
    nl_asm_held_t *h = &as->duty;
    uint16_t seq;
    uint8_t bit;
    int j;
    if (f->id == HIL_PROTOCOL_CMD_DUTY_A_FRAME_ID) {
        struct hil_protocol_cmd_duty_a_t a;
        (void)hil_protocol_cmd_duty_a_unpack(&a, f->data, f->len);
        seq = a.seq;
        bit = PART_A;
    } else if (f->id == HIL_PROTOCOL_CMD_DUTY_B_FRAME_ID) {
        struct hil_protocol_cmd_duty_b_t b;
        (void)hil_protocol_cmd_duty_b_unpack(&b, f->data, f->len);
        seq = b.seq;
        bit = PART_B;
    } else {
        struct hil_protocol_cmd_duty_c_t c;
        (void)hil_protocol_cmd_duty_c_unpack(&c, f->data, f->len);
        seq = c.seq;
        bit = PART_C;
    }
    if (asm_add(h, bit, seq, r) < 0) {
        return NL_MSG_NONE;
    }
    if (bit == PART_A) {
        struct hil_protocol_cmd_duty_a_t a;
        (void)hil_protocol_cmd_duty_a_unpack(&a, f->data, f->len);
        as->duty_raw[0] = a.duty0;
        as->duty_raw[1] = a.duty1;
        as->duty_raw[2] = a.duty2;
    } else if (bit == PART_B) {
        struct hil_protocol_cmd_duty_b_t b;
        (void)hil_protocol_cmd_duty_b_unpack(&b, f->data, f->len);
        as->duty_raw[3] = b.duty3;
        as->duty_raw[4] = b.duty4;
        as->duty_raw[5] = b.duty5;
    } else {
        struct hil_protocol_cmd_duty_c_t c;
        (void)hil_protocol_cmd_duty_c_unpack(&c, f->data, f->len);
        as->duty_exec = c.exec_time_ns;
        as->duty_status = c.status;
        as->duty_n = c.n_duties;
    }
    if (h->have != (PART_A | PART_B | PART_C)) {
        return NL_MSG_NONE;
    }
    if (h->unordered) {
        r->dec_out_of_order++;
    }
    memset(cmd, 0, sizeof *cmd);
    cmd->seq = (uint16_t)h->held_seq;
    cmd->exec_time_ns = as->duty_exec;
    cmd->status = as->duty_status;
    cmd->n_duties = as->duty_n;
    cmd->both_forms = as->duty_n == 0u ? 1u : 0u; /* n_duties 0: the sender set both forms */
    for (j = 0; j < 6; ++j) {
        cmd->duty_raw[j] = j < as->duty_n ? as->duty_raw[j] : 0u;
    }
    asm_clear(h);
    return NL_MSG_COMMAND;
}

int nl_decode(nl_cmd_asm_t *as, const hil_core_frame_t *f, nl_result_t *r, nl_cmd_t *cmd, uint8_t *fault_code,
              uint32_t *fault_detail)
{
    const uint8_t want = known_length(f->id);
    int msg = NL_MSG_NONE;
    r->dec_frames++;
    if (want == 0u) {
        r->dec_unknown_id++;
        return NL_MSG_NONE;
    }
    if (f->len != want) {
        r->dec_bad_length++;
        return NL_MSG_NONE;
    }
    switch (f->id) {
    case HIL_PROTOCOL_CMD_FD_FRAME_ID: {
        struct hil_protocol_cmd_fd_t c;
        (void)hil_protocol_cmd_fd_unpack(&c, f->data, f->len);
        if (c.n_states < 1u || c.n_states > 3u) {
            r->dec_bad_value++;
            return NL_MSG_NONE;
        }
        cmd->seq = c.seq;
        cmd->n_states = c.n_states;
        cmd->states[0] = c.state0;
        cmd->states[1] = c.state1;
        cmd->states[2] = c.state2;
        cmd->durations_ns[0] = c.duration0;
        cmd->durations_ns[1] = c.duration1;
        cmd->durations_ns[2] = c.duration2;
        cmd->vector_id = c.vector_id;
        cmd->candidates = c.candidates;
        cmd->exec_time_ns = c.exec_time_ns;
        cmd->status = c.status;
        cmd->mirror = c.mirror == 1u ? 1u : 0u;
        cmd->n_duties = 0u;
        memset(cmd->duty_raw, 0, sizeof cmd->duty_raw);
        cmd->both_forms = 0u;
        msg = NL_MSG_COMMAND;
        break;
    }
    case HIL_PROTOCOL_CMD_A_FRAME_ID:
    case HIL_PROTOCOL_CMD_B_FRAME_ID:
    case HIL_PROTOCOL_CMD_C_FRAME_ID:
        msg = cmd_part(as, f, r, cmd);
        break;
    case HIL_PROTOCOL_CMD_DUTY_FD_FRAME_ID: {
        struct hil_protocol_cmd_duty_fd_t c;
        (void)hil_protocol_cmd_duty_fd_unpack(&c, f->data, f->len);
        memset(cmd, 0, sizeof *cmd);
        cmd->seq = c.seq;
        cmd->n_duties = c.n_duties;
        cmd->both_forms = c.n_duties == 0u ? 1u : 0u; /* n_duties 0: the sender set both forms */
        cmd->duty_raw[0] = c.duty0;
        cmd->duty_raw[1] = c.duty1;
        cmd->duty_raw[2] = c.duty2;
        cmd->duty_raw[3] = c.n_duties > 3u ? c.duty3 : 0u;
        cmd->duty_raw[4] = c.n_duties > 3u ? c.duty4 : 0u;
        cmd->duty_raw[5] = c.n_duties > 3u ? c.duty5 : 0u;
        cmd->vector_id = c.vector_id;
        cmd->candidates = c.candidates;
        cmd->exec_time_ns = c.exec_time_ns;
        cmd->status = c.status;
        msg = NL_MSG_COMMAND;
        break;
    }
    case HIL_PROTOCOL_CMD_DUTY_A_FRAME_ID:
    case HIL_PROTOCOL_CMD_DUTY_B_FRAME_ID:
    case HIL_PROTOCOL_CMD_DUTY_C_FRAME_ID:
        msg = duty_part(as, f, r, cmd);
        break;
    case HIL_PROTOCOL_FAULT_TARGET_FRAME_ID:
    case HIL_PROTOCOL_FAULT_HOST_FRAME_ID: {
        struct hil_protocol_fault_target_t ft; /* FaultHost has this layout */
        (void)hil_protocol_fault_target_unpack(&ft, f->data, f->len);
        *fault_code = ft.code;
        *fault_detail = ft.detail;
        r->dec_messages++;
        return NL_MSG_FAULT;
    }
    case HIL_PROTOCOL_MEAS_A_FRAME_ID:
    case HIL_PROTOCOL_MEAS_B_FRAME_ID:
    case HIL_PROTOCOL_MEAS6_A_FRAME_ID:
    case HIL_PROTOCOL_MEAS6_C_FRAME_ID:
    case HIL_PROTOCOL_MEAS6_B_FRAME_ID:
        return NL_MSG_NONE; /* measurement parts from a target: counted as frames only */
    default: /* the single-frame messages (ConfigAck, Heartbeat, ...): delivered, nothing to do here */
        r->dec_messages++;
        if (f->id == HIL_PROTOCOL_CONFIG_ACK_FRAME_ID) {
            r->dec_config_acks++;
        }
        return NL_MSG_NONE;
    }
    if (msg == NL_MSG_COMMAND) {
        r->dec_messages++;
    }
    return msg;
}

/* An id whose sender in hil.dbc is the target. */
static int target_sends(uint32_t id)
{
    switch (id) {
#define TARGET_CASE(frame_id, length, target, command) case frame_id: return target;
    HIL_FRAMES(TARGET_CASE)
#undef TARGET_CASE
    default: return 0;
    }
}

/* A Command frame of hil.dbc (every part carries seq 0|16@1+). */
static int is_command(uint32_t id)
{
    switch (id) {
#define COMMAND_CASE(frame_id, length, target, command) case frame_id: return command;
    HIL_FRAMES(COMMAND_CASE)
#undef COMMAND_CASE
    default: return 0;
    }
}

int nl_bus_frame(const hil_core_frame_t *f, int32_t expected, int32_t have_reply, int32_t prev_answered,
                 int32_t controller_id)
{
    int32_t seq;
    const uint8_t want = known_length(f->id);
    if (want != 0u && f->len != want) {
        return target_sends(f->id) ? NL_BUS_SUSPECT : NL_BUS_FOREIGN; /* the target's frames have their length */
    }
    if (is_command(f->id)) {
        seq = (int32_t)((uint32_t)f->data[0] | ((uint32_t)f->data[1] << 8));
        if (seq == expected && !have_reply) {
            return NL_BUS_TARGET;
        }
        if (expected >= 0 && seq == ((expected - 1) & 0xFFFF) && !prev_answered) {
            return NL_BUS_TARGET;
        }
        return NL_BUS_SUSPECT;
    }
    switch (f->id) {
    case HIL_PROTOCOL_FAULT_TARGET_FRAME_ID:
        if (f->data[0] != HIL_FW_NODE_TARGET || f->data[1] == HIL_FW_STATUS_OK || f->data[1] >= HIL_FW_STATUS_COUNT) {
            return NL_BUS_SUSPECT;
        }
        {
            const uint32_t detail = (uint32_t)f->data[2] | ((uint32_t)f->data[3] << 8) | ((uint32_t)f->data[4] << 16)
                                    | ((uint32_t)f->data[5] << 24);
            /* the answers to a Setpoint name what it asked: not_implemented its controller id, invalid_config its
             * mode; another controller id, or a mode that is no Mode value, answered no Setpoint of ours */
            if (f->data[1] == HIL_FW_STATUS_NOT_IMPLEMENTED && detail != (uint32_t)controller_id) {
                return NL_BUS_SUSPECT;
            }
            if (f->data[1] == HIL_FW_STATUS_INVALID_CONFIG && detail >= HIL_FW_MODE_COUNT) {
                return NL_BUS_SUSPECT;
            }
        }
        return NL_BUS_TARGET;
    case HIL_PROTOCOL_CONFIG_ACK_FRAME_ID:
    case HIL_PROTOCOL_HEARTBEAT_TARGET_FRAME_ID:
        return NL_BUS_TARGET;
    default:
        return NL_BUS_FOREIGN;
    }
}

int nl_host_id(uint32_t id)
{
    return known_length(id) != 0u && !target_sends(id);
}
