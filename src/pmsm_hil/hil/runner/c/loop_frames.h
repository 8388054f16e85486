/*
 * Host side of the frame protocol for the native loop: Measurement and Setpoint encoded with the generated
 * codec (raw values computed as src/pmsm_hil/protocol/codec.py does: round half to even, saturation, angle wrap), and the
 * host's Command decoder (src/pmsm_hil/protocol/codec.py FrameDecoder with an unordered Assembler) with its counters.
 */
#ifndef HIL_NATIVE_LOOP_FRAMES_H
#define HIL_NATIVE_LOOP_FRAMES_H

#include <stdint.h>

#include "hil_target_core.h"
#include "loop.h"

/* A decoded Command (src/pmsm_hil/protocol/messages.py Command). */
typedef struct {
    uint16_t seq;
    uint8_t n_states;
    uint8_t states[3];
    uint32_t durations_ns[3];
    uint8_t vector_id;
    uint8_t candidates;
    uint8_t status;
    uint8_t mirror;
    uint32_t exec_time_ns;
    uint8_t n_duties;          /* 0: switching states; 3 or 6: the duty-cycle form (duty_raw, codes of hil.dbc) */
    uint16_t duty_raw[6];
    uint8_t both_forms;        /* 1: a duty Command with n_duties 0: its sender set both forms (rule `duty`) */
} nl_cmd_t;

/* Held parts of one Command kind (src/pmsm_hil/protocol/assembler.py Assembler, unordered). */
typedef struct {
    int32_t held_seq;          /* -1: none held */
    uint8_t have;              /* part bits */
    uint8_t unordered;
} nl_asm_held_t;

/* The classic-CAN Command assembler (three parts, any order, a new seq replaces held parts). */
typedef struct {
    nl_asm_held_t states;      /* the switching-state Command's parts (CmdA/B/C) */
    uint8_t a_states[3], a_n, a_vector_id;
    uint32_t a_d0;
    uint32_t b_d1, b_d2;
    uint8_t b_candidates;
    uint32_t c_exec;
    uint8_t c_status, c_mirror;
    /* the duty-cycle Command's parts (CmdDutyA/B/C), assembled apart as the Python decoder does */
    nl_asm_held_t duty;
    uint16_t duty_raw[6];
    uint32_t duty_exec;
    uint8_t duty_status, duty_n;
} nl_cmd_asm_t;

#define NL_MSG_NONE 0
#define NL_MSG_COMMAND 1
#define NL_MSG_FAULT 2

/* Measurement frames of one period into out[0..*n-1]; 0 ok, else -1 with *bad_field (0 theta_e, 1..legs the
 * currents, legs+1 omega_m, legs+2 vdc) and *bad_value. */
int nl_encode_meas(const nl_config_t *c, uint16_t seq, const double *currents, double theta_e, double omega_m,
                   hil_core_frame_t *out, int *n, int32_t *bad_field, double *bad_value);

/* The Setpoint frame (enable, mode, reference [rad/s or N*m] as float32, controller id). */
void nl_encode_setpoint(uint8_t enable, uint8_t mode, double reference, uint8_t controller_id,
                        hil_core_frame_t *out);

/* Feed one frame from the target to the host decoder: NL_MSG_COMMAND (*cmd filled), NL_MSG_FAULT
 * (*fault_code, *fault_detail) or NL_MSG_NONE; counters in r (dec_*). */
int nl_decode(nl_cmd_asm_t *as, const hil_core_frame_t *f, nl_result_t *r, nl_cmd_t *cmd, uint8_t *fault_code,
              uint32_t *fault_detail);

/* Who sent a frame the host received on a shared bus (hil.dbc; src/pmsm_hil/protocol/links/shared_bus.py): */
#define NL_BUS_TARGET 0   /* it can be the target's */
#define NL_BUS_FOREIGN 1  /* an id the target never sends (hil.dbc: sender not Target) */
#define NL_BUS_SUSPECT 2  /* a target id with content the target cannot have sent */
/* A Command part is the target's when it answers the open Measurement seq `expected` before its reply is complete
 * (`have_reply` 0), or the previous seq still unanswered (`prev_answered` 0); a FaultTarget when it has its length,
 * node 1 (target), a Status code 1..6 and, for not_implemented, the run's `controller_id` as detail, for
 * invalid_config a Mode value (0, 1) (the target answered our Setpoint, not another node's); ConfigAck and
 * HeartbeatTarget by their id. */
int nl_bus_frame(const hil_core_frame_t *f, int32_t expected, int32_t have_reply, int32_t prev_answered,
                 int32_t controller_id);

/* 1: an id hil.dbc gives the host (Measurement, Setpoint, ConfigParam, FaultHost, HeartbeatHost). */
int nl_host_id(uint32_t id);

#endif
