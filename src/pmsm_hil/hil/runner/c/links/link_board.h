/*
 * The native loop's link to the virtual STM32G4 board running register-level firmware
 * (src/pmsm_hil/sim_target/stm32g4/link.py, in this process): a period's Measurement frame (MeasFd) is decoded here
 * and handed to the board as plain numbers through one call (`period`), and the duty-cycle Command the board
 * answers with comes back as plain numbers and is encoded here (CmdDutyFd) with the generated codec, the raw values
 * as src/pmsm_hil/protocol/codec_duty.py computes them. Every other frame, and a reply the board keeps in Python
 * (a switching-state Command, frames of its FDCAN1 bus, configuration answers), goes through the callback link
 * `py` (loop_py.h): a receive asks Python only while the board says it may have something (`py_pending`). The
 * board answers inside `send`, yet its flags are the callback link's (0): records equal those of the callback link
 * alone. No allocation.
 */
#ifndef HIL_NATIVE_LINK_BOARD_H
#define HIL_NATIVE_LINK_BOARD_H

#include <stdint.h>

#include "nl_link.h"

/* A Measurement as the board takes it: the decoded values (raw x scale, in double as the Python decoder). */
typedef struct {
    uint16_t seq;
    uint8_t status;
    double i_a, i_b, i_c;      /* [A] */
    double theta_e;            /* [rad] */
    double omega_m;            /* [rad/s] */
    double vdc;                /* [V] */
} nl_board_meas_t;

/* What the board answered (nl_board_cmd_t.form). */
#define NL_BOARD_HELD 0        /* nothing here: the board queued its reply (if any) in Python */
#define NL_BOARD_DUTIES 1      /* a three-phase duty-cycle Command: duties, exec_time_ns */
#define NL_BOARD_OUTPUTS 2     /* a three-phase duty-cycle Command with exec_time_ns, its duties from `outputs` */

typedef struct {
    uint8_t form;              /* NL_BOARD_* */
    double duties[3];          /* the legs' duties (0..1; outside or NaN: the wire's codes) */
    int64_t exec_time_ns;      /* saturated to 0..2^32-1 on the wire */
} nl_board_cmd_t;

/* One control period of the board for Measurement *m: 0 with *cmd filled, -1 when the board failed (the callback
 * link's error: the loop stops). */
typedef int (*nl_board_period_fn)(void *ctx, const nl_board_meas_t *m, nl_board_cmd_t *cmd);

/* The board's models in C, called here without Python (null: the board does it in `period`): `inputs(inputs_user,
 * {i_a, i_b, i_c, vdc})` before `period` (the ADC pair's table of pin voltages), `outputs(outputs_user, {i_a, i_b,
 * i_c}, duties)` after a `period` that answered NL_BOARD_OUTPUTS (TIM1's compare duties: 1, 0 when it has none). */
typedef void (*nl_board_inputs_fn)(void *user, const double *values);
typedef int (*nl_board_outputs_fn)(void *user, const double *currents, double *duties);

/* The board's common period in C (src/pmsm_hil/sim_target/stm32g4/c/board_period.c; null: every period through
 * `period`): `fast(fast_user, {i_a, i_b, i_c, theta_e, omega_m, vdc}, &exec_time_ns)` after `inputs`, while Python
 * has nothing pending: 1 the period ran and TIM1's outputs are on (the duties from `outputs`), 0 `period` runs it
 * (or finishes what `fast` began). */
typedef int (*nl_board_fast_fn)(void *user, const double *values, int64_t *exec_time_ns);

#define NL_BOARD_QUEUE 2

typedef struct {
    nl_link_t py;              /* the callback link: every other frame, and what the board holds in Python */
    nl_board_period_fn period;
    void *ctx;                 /* the board's Python end (`period`'s ctx) */
    double scale_i, scale_theta, scale_omega, scale_vdc; /* MeasFd's signal scales (the Python codec's) */
    nl_board_inputs_fn inputs;
    void *inputs_user;
    nl_board_outputs_fn outputs;
    void *outputs_user;
    nl_board_fast_fn fast;
    void *fast_user;
    int32_t py_pending;        /* 0: a receive in Python would find nothing and do nothing (set by Python) */
    int32_t q_head, q_n;
    hil_core_frame_t q[NL_BOARD_QUEUE];
    nl_link_stats_t stats;     /* frames_tx: Measurements taken here; frames_rx: Commands returned from here */
} nl_board_link_t;

/* Send one frame: a MeasFd frame runs the board's period, any other goes to `py`. 0 ok, -1 the board failed. */
int nl_board_send(nl_board_link_t *s, const hil_core_frame_t *f);

/* The next reply: a Command queued here first, then (while py_pending) what `py` returns. */
int nl_board_recv(nl_board_link_t *s, hil_core_frame_t *f, int64_t deadline_ns);

/* *l: the board's link on *s (s->py, period, ctx and the scales set by the caller). */
void nl_board_link(nl_link_t *l, nl_board_link_t *s);

#endif
