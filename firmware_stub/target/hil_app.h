/*
 * The firmware API: what a user's firmware implements to run behind the HIL target core
 * (docs/firmware_api.md). The core (hil_target_core.c) speaks the frame protocol -- decodes
 * Measurement / Setpoint / ConfigParam / Heartbeat frames with the generated codec, answers with
 * Command / ConfigAck / FaultTarget / HeartbeatTarget -- and calls these six functions. The same
 * firmware sources build for the host (SIL: a shared library, `hil run --target sil:PATH`) and for
 * the emulated Cortex-M4F (`hil run --target qemu:PATH.elf`).
 *
 * Units are SI: currents A, angle rad (electrical), speed rad/s (mechanical), voltage V, time ns.
 * Every call comes from one thread (the core's caller); none is re-entered.
 */
#ifndef HIL_APP_H
#define HIL_APP_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" { /* a C++ firmware defines these functions with C linkage: the core (C) calls them */
#endif

#define HIL_APP_MAX_PHASES 6
#define HIL_APP_MAX_STATES 3

/* Return codes. */
#define HIL_APP_OK 0
#define HIL_APP_E_PARAM (-1)           /* ConfigParam rejected: ConfigAck status 5 invalid_config */
#define HIL_APP_E_NOT_IMPLEMENTED (-2) /* controller id not implemented: FaultTarget 6 not_implemented */
#define HIL_APP_E_SETPOINT (-3)        /* mode / reference rejected: FaultTarget 5 invalid_config */

/* Measurement k, sampled at t_ns = k * Ts (virtual time: k counts every Measurement received since boot). */
typedef struct {
    uint64_t t_ns;                  /* sample time [ns] */
    uint16_t seq;                   /* frame sequence number (the core echoes it) */
    uint8_t n_phases;               /* 3 or 6 */
    uint8_t status;                 /* plant status code from the frame (informational) */
    float i[HIL_APP_MAX_PHASES];    /* phase currents [A]: a, b, c (then u, v, w) */
    float theta_e;                  /* electrical angle [rad], 0..2*pi */
    float omega_m;                  /* mechanical speed [rad/s] */
    float vdc;                      /* measured DC link [V] */
} hil_app_meas_t;

/* Command k, applied by the plant over [(k+1)Ts, (k+2)Ts). The core zeroes it before hil_app_step.
 * Two forms: switching states (n_duties 0: n_states, states, durations_ns, mirror) or duty cycles
 * (n_duties 3 or 6: duty[0..n_duties-1], legs a, b, c then u, v, w): the fraction of the carrier period
 * each leg's upper switch is on, centre-aligned PWM whose carrier period is Ts, valley (all legs low) at
 * the period start; the plant computes the switching instants of the carrier comparison (all 7 segments
 * 0-x-xy-7-xy-x-0), dead time and minimum pulse included. A duty outside 0..1 or NaN is a DUT-contract
 * finding at the host (never clamped silently). Set one form: duties with n_states, durations_ns or mirror set too
 * is reported by the core as a Command with n_duties 0 (the host's rule `duty`: "both forms set"). See
 * docs/firmware_api.md, "Duty-cycle commands". */
typedef struct {
    uint8_t n_states;                           /* 1..3 sub-intervals */
    uint8_t states[HIL_APP_MAX_STATES];         /* switching codes 4*Sa + 2*Sb + Sc (six phases: 6 bits) */
    uint32_t durations_ns[HIL_APP_MAX_STATES];  /* sub-interval lengths [ns], sum = Ts (mirror: see docs) */
    uint8_t mirror;                             /* 1: plant applies states then states[n-2..0] */
    uint8_t vector_id;                          /* diagnostic, logged (0: nothing to report) */
    uint8_t candidates;                         /* candidates evaluated (0: not reported) */
    uint8_t status;                             /* HIL status code, 0 ok */
    float torque_ref;                           /* debug outputs, not on the wire (SIL shows them) */
    float id_ref;
    float iq_ref;
    uint8_t n_duties;                           /* 0: switching states above; 3 or 6: the duty form */
    float duty[HIL_APP_MAX_PHASES];             /* per-leg duty 0..1 (the first n_duties are sent) */
} hil_app_cmd_t;

/* Once at boot (and again when the host's SIL loader starts a run). */
void hil_app_init(void);

/* ConfigParam param_id (HIL_FW_P_* of hil_ids.h, SI units): HIL_APP_OK, or HIL_APP_E_PARAM to reject.
 * Acknowledge parameters you do not use with HIL_APP_OK. */
int hil_app_config(uint8_t param_id, float value);

/* Setpoint.controller_id changed: select it. HIL_APP_OK or HIL_APP_E_NOT_IMPLEMENTED (the previous
 * selection stays; the core sends FaultTarget not_implemented and disables). */
int hil_app_select(uint8_t controller_id);

/* Start the control law afresh (integrators, filters, last applied state); the core calls it on every
 * rising enable edge, before hil_app_setpoint. */
void hil_app_reset(void);

/* Setpoint: enable 0/1, mode 0 speed (reference rad/s mechanical) or 1 torque (N*m).
 * HIL_APP_OK or HIL_APP_E_SETPOINT (the core sends FaultTarget invalid_config and disables). */
int hil_app_setpoint(uint8_t enable, uint8_t mode, float reference);

/* One control step while enabled: measurement k -> command k. The core measures its execution
 * (board clock; instruction counts on the emulated MCU) around this call only. */
void hil_app_step(const hil_app_meas_t *m, hil_app_cmd_t *cmd);

#ifdef __cplusplus
}
#endif

#endif
