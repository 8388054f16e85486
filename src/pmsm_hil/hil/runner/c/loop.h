/*
 * The native period loop: plant sample, sensor model, Measurement encode (generated codec), the frames sent
 * over the run's link (nl_link.h; in process: the C target core) and the reply received, Command decode,
 * DUT-contract checks, plant advance, the period record -- the same steps, in the same order and with the same
 * arithmetic, as tests/oracle/closed_loop.py (the reference).
 *
 * The loop runs in its own thread over the whole run and writes each block of NL_BLOCK periods into a ring
 * of NL_RING slots (period records in PERIOD_DTYPE layout, raw frames in FRAME_DTYPE layout, metrics-window
 * trace rows, lateness); Python drains full slots to the run's sink and hands them back with the next
 * block's sensor noise. All memory is allocated by the caller before the run: nothing is allocated in the
 * loop. Units: SI (A, rad, rad/s, N*m, V, s), times in ns where named so.
 */
#ifndef HIL_NATIVE_LOOP_H
#define HIL_NATIVE_LOOP_H

#include <stdint.h>

#define NL_BLOCK 1000              /* periods per slot (= ClosedLoop.BLOCK) */
#define NL_RING 8                  /* slots */
#define NL_FRAMES_PER_PERIOD 8     /* frame records per period: Setpoint + Measurement (<= 3) + Command (<= 3) */
#define NL_FINDINGS 100            /* contract findings kept per slot (all are counted): >= MAX_KEPT_VIOLATIONS, so the
                                      * first findings of a run are the Python loop's whatever a block holds */
#define NL_REF_CHANGES 16          /* speed-reference changes per run */
#define NL_LOAD_BREAKPOINTS 8      /* load breakpoints inside one period (= MAX_LOAD_BREAKPOINTS) */
#define NL_RULES 6                 /* missing, sequence, state_code, durations, frame, duty (contract.RULES order) */
#define NL_LATE_BINS 1024          /* real time: lateness histogram bins of 1 us (0..1022 us, the last from 1023 us on) */

/* The contract rules (index into nl_result_t.by_rule). */
#define NL_RULE_MISSING 0
#define NL_RULE_SEQUENCE 1
#define NL_RULE_STATE_CODE 2
#define NL_RULE_DURATIONS 3
#define NL_RULE_FRAME 4
#define NL_RULE_DUTY 5

/* What a finding says (nl_finding_t.what). */
#define NL_WHAT_MISSING 0        /* v[0] = seq */
#define NL_WHAT_SECOND 1         /* a second Command for v[0] = seq */
#define NL_WHAT_OTHER_SEQ 2      /* Command seq v[0] while the period's is v[1] */
#define NL_WHAT_DECODER_SEQ 3    /* v[0] frames with an old/repeated seq; v[1..4] stale, duplicate, out_of_order, mixed */
#define NL_WHAT_DECODER_FRAME 4  /* v[0] frames rejected; v[1] bad_length, v[2] bad_value */
#define NL_WHAT_STATE_CODE 5     /* state v[0] = code v[1] outside 0..v[2] */
#define NL_WHAT_DURATIONS 6      /* durations fill v[0] ns, Ts = v[1] ns (mirrored when the Command is) */
#define NL_WHAT_DUTY_COUNT 7     /* v[0] duties for a machine with v[1] legs */
#define NL_WHAT_DUTY 8           /* duty v[0] has the wire code v[1] (65535 NaN, else above 65520: outside 0..1) */
#define NL_WHAT_BOTH_FORMS 9     /* a duty Command with n_duties 0: its sender set both forms */

/* How the run ended (nl_result_t.end). */
#define NL_END_RUNNING 0
#define NL_END_COMPLETED 1
#define NL_END_VIOLATION 2       /* more findings than `tolerate` */
#define NL_END_WATCHDOG 3        /* target silent for watchdog_periods */
#define NL_END_FAULT 4           /* FaultTarget received: fault_code, fault_detail */
#define NL_END_TRIP 5            /* plant trip at period end_period (peak_current: the in-period peak) */
#define NL_END_PLANT_ERROR 6     /* the plant kernel refused the period: plant_rc */
#define NL_END_ENCODE_ERROR 7    /* a Measurement value the codec cannot encode: encode_field, encode_value */
#define NL_END_INTERRUPTED 8     /* nl_stop() */
#define NL_END_HOST_STALL 9      /* lockstep: the target's process could not run for stall_limit_ns (host_stall_wait_ns) */

#define NL_PLANT_E_BREAKPOINTS (-100) /* more load breakpoints inside one period than NL_LOAD_BREAKPOINTS */
#define NL_PLANT_E_KERNEL (-101)      /* no machine kernel, another MK_ABI_VERSION, or legs/format it cannot serve */
#define NL_PLANT_E_LOAD_FMU (-102)    /* the load FMU failed (nl_fmu_t: failed_call, status, t_fail, message) */

/* The Measurement frames a machine is measured with (nl_codec_cfg_t.meas_format; loop_frames.c encodes them). */
#define NL_MEAS_3 0              /* three currents: MeasA + MeasB (classic CAN) or MeasFd */
#define NL_MEAS_6 1              /* six currents: Meas6A + Meas6C + Meas6B (classic CAN) or MeasFd6 */
#define NL_MEAS_FORMATS 2

/* nl_period_t and nl_frame_rec_t: generated from src/pmsm_hil/hil/records.py (PERIOD_DTYPE, FRAME_DTYPE) by
 * `python -m pmsm_hil.hil.gen_records`, with compile-time checks of their size and field offsets. */
#include "records.h"

/* One DUT-contract finding; Python words it as the Python loop does. */
typedef struct {
    uint32_t period;
    uint8_t rule;              /* NL_RULE_* */
    uint8_t what;              /* NL_WHAT_* */
    uint8_t has_cmd;           /* the Command fields below are valid */
    uint8_t n_states;
    uint8_t mirror;
    uint8_t states[3];
    uint16_t cmd_seq;
    uint32_t durations_ns[3];
    int64_t v[5];
    uint8_t n_duties;          /* the duty-cycle form: duty wire codes (loop_frames.h nl_cmd_t) */
    uint16_t duty_raw[6];
} nl_finding_t;

/* What a SIL target in its own process shares with the host (memory both map; target_serve.c writes it after
 * each step, before the step's Command goes out, so the host reads it for the Command it just received): control
 * steps run and the torque reference [N*m] of the last one (hil_app_cmd_t's debug output). */
typedef struct {
    uint32_t steps;
    float torque_ref;
} nl_sil_debug_t;

/* The run's configuration, fixed for the run and written by Python before nl_run (loop_config.py, one fill per
 * group). Its groups are RunConfig's (src/pmsm_hil/hil/runner/run_groups.py): machine; scenario and load
 * (operation); target and link; timing and real time; sensors; outputs. */

/* machine: the plant's machine kernel (machine_kernel.h), the Python plant's own structs it works on, its limits */
typedef struct {
    int32_t legs;              /* measured phase currents = the kernel's legs (a loop bound, never a branch) */
    int32_t max_state;         /* the highest gate code of the machine (the DUT contract's state_code rule) */
    const struct mk_kernel *kernel;
    void *plant_params;
    void *plant_state;
    void *plant_scratch;       /* timing.adc_delay_ns > 0: state_size bytes for a copy of the plant state */
    double vdc;                /* measured DC link sent in every Measurement [V] */
    double i_trip, w_trip;     /* [A], [rad/s] */
} nl_machine_cfg_t;

/* scenario and load: periods, speed reference, mechanics and load */
typedef struct {
    int64_t n_total;           /* periods of the run */
    int64_t n_settle;          /* first period of the metrics window */
    double rpm_to_rad_s;
    int32_t dyno;              /* 1: dyno (speed held at the reference), 0: inertia */
    int32_t inertia;           /* the plant's mechanics at the start: 1 inertia (load profile applies) */
    int32_t n_load;            /* load profile points (time [s], torque [N*m]), any number (the caller's arrays) */
    const double *load_t;
    const double *load_v;
    struct nl_fmu *load_fmu;   /* the load as an FMU (loop_fmu.h), opened and initialised by the caller; NULL: the
                                * load profile above. Each period: speed at its start in, torque held out, doStep */
    int32_t n_ref;             /* speed reference [rpm] from period ref_k[j] on */
    int64_t ref_k[NL_REF_CHANGES];
    double ref_rpm[NL_REF_CHANGES];
} nl_operation_cfg_t;

/* the Measurement's frames and the codec's scales and raw limits (from hil.dbc) */
typedef struct {
    int32_t fd;                /* 1: CAN FD frames, 0: classic CAN parts */
    int32_t meas_format;       /* NL_MEAS_*: the Measurement frames of the machine (MachineLayout.measurement) */
    double s_i, s_th, s_w, s_v;
    int32_t i_min, i_max, w_min, w_max, v_min, v_max, th_mod;
} nl_codec_cfg_t;

/* target and link: the link, the codec, the controller, the DUT contract, the lockstep waits, the target's state */
typedef struct {
    /* the link to the target (nl_link.h; required): the in-process C target core (link_core.h), a wire to another
     * process or a board (UDP, serial, SocketCAN), or the callback link through Python (loop_py.h) */
    const struct nl_link *link;
    nl_codec_cfg_t codec;
    int32_t controller_id;
    int32_t mode_speed;        /* Setpoint mode value of speed control */
    int32_t tolerate;
    int32_t watchdog_periods;
    int64_t lockstep_timeout_ns; /* lockstep over a link: how long to wait for a Command [ns]: the target's own time
                                  * when target_pid is set (loop_stall.h), else wall time */
    int32_t target_pid;        /* the target's process the host can observe (0: none, e.g. a board: wall time) */
    const uint64_t *guest_insns; /* an emulated MCU's executed instructions, counted by QEMU's plugin in shared memory
                                  * (NULL: none): its lockstep time is its own progress (nl_guest_available) */
    int64_t guest_ns_per_insn; /* the virtual time of one of its instructions [ns] (-icount shift) */
    int64_t stall_limit_ns;    /* lockstep: the longest wall time one wait for a Command may last while the host
                                * stalls the target's process (then NL_END_HOST_STALL) [ns] */
    const nl_sil_debug_t *sil_debug; /* a SIL target in its own process: its debug outputs, NULL: none */
    int32_t shared_bus;        /* 1: a CAN bus other nodes may share (loop.c from_target_node): a frame that cannot be
                                * the target's is bus traffic (bus_foreign_frames, bus_suspect_frames), no finding */
    /* target state the Python set-up left (a Fault while configuring) */
    int32_t fault_pending;
    uint8_t fault_code_in;
    uint32_t fault_detail_in;
    int32_t first_n_duties;    /* the command of period 0, before the target's first reply: 0 the full-period zero
                                * vector; 3 or 6 these duties (wire codes): the outputs a board has at the run's start
                                * (TargetConnection.first_duties: its open bridge while its outputs are off) */
    uint16_t first_duty_raw[6];
} nl_target_link_cfg_t;

/* timing and real time */
typedef struct {
    int64_t ts_ns;
    double ts_s;
    int32_t pwm_double;        /* duty-cycle Commands: 0 single update, 1 double (pwm_duty.h halves) */
    int64_t adc_delay_ns;      /* the Measurement is sampled this long after the period start [ns] (0: at it) */
    int32_t realtime;
    int32_t miss_zero;         /* miss policy: 1 zero vector, 0 hold */
    int64_t overrun_ns;
    int64_t spin_ns;           /* busy-wait at most this long before a period start; sleep before that */
    int32_t rt_priority;       /* SCHED_FIFO priority, 0: none */
    int32_t cpu;               /* CPU for the loop thread, -1: any */
    int32_t lock_memory;       /* mlockall for the run */
} nl_timing_cfg_t;

/* sensors */
typedef struct {
    int32_t ideal;
    double noise_std;          /* [A]; noise values come per slot */
    double adc_lsb;            /* [A], 0: none */
    double enc_step;           /* encoder step [rad electrical], 0: ideal angle */
    double two_pi;
} nl_sensors_cfg_t;

/* outputs: frame records and the plant's trace */
typedef struct {
    int32_t record_frames;
    double *plant_trace;       /* the plant's trace buffer (periods before the window) */
    int32_t trace_cap;         /* trace rows one period may write */
    double trace_dt;           /* [s], 0: no trace */
    int32_t trace_columns;
} nl_outputs_cfg_t;

typedef struct {
    nl_machine_cfg_t machine;
    nl_operation_cfg_t operation;
    nl_target_link_cfg_t target_link;
    nl_timing_cfg_t timing;
    nl_sensors_cfg_t sensors;
    nl_outputs_cfg_t outputs;
    double nan;                /* the NaN the Python loop writes (bit pattern kept) */
} nl_config_t;

/* One block of the ring. `trace` (rows x trace_columns doubles) is the caller's. */
typedef struct {
    nl_period_t periods[NL_BLOCK];
    nl_frame_rec_t frames[NL_BLOCK * NL_FRAMES_PER_PERIOD];
    int64_t lateness_ns[NL_BLOCK];
    nl_finding_t findings[NL_FINDINGS];
    double noise[NL_BLOCK * 6];
    double *trace;
    int64_t trace_rows_cap;
    int32_t n_periods;
    int32_t n_frames;
    int32_t n_findings;
    int64_t n_trace_rows;
} nl_slot_t;

/* Counters and ending, read by Python after the run (and between blocks). */
typedef struct {
    int32_t end;               /* NL_END_* */
    int64_t completed_periods;
    int64_t end_period;        /* the period the ending was found in */
    int64_t lost_commands;
    int64_t deadline_misses;
    int64_t stale_commands;
    int64_t overruns;
    int64_t max_wait_ns;
    int64_t host_stalls;       /* lockstep waits the lockstep timeout did not end because the host stopped or starved
                                * the target's process */
    int64_t host_stall_ns;     /* the time the target could not run in those waits [ns] */
    int64_t host_stall_wait_ns; /* NL_END_HOST_STALL: the wall time of the wait that ended the run [ns] */
    int64_t violation_count;
    int64_t by_rule[NL_RULES];
    int64_t candidate_checked;
    int64_t candidate_misses;
    int64_t silent;            /* periods without a Command in a row */
    uint8_t fault_code;
    uint32_t fault_detail;
    double peak_current;       /* trip: the period's in-period peak |i| [A] */
    int32_t plant_rc;
    int32_t plant_detail;      /* NL_PLANT_E_BREAKPOINTS: the breakpoints inside the period */
    int32_t encode_field;      /* index into the Measurement's fields (Python names it) */
    double encode_value;
    int64_t frames_tx, frames_rx;
    /* host decoder counters (DecodeStats) */
    int64_t dec_frames, dec_messages, dec_unknown_id, dec_bad_length, dec_bad_value, dec_stale, dec_duplicate,
        dec_out_of_order, dec_mixed_seq;
    int64_t dec_config_acks;   /* ConfigAcks received in the run: late answers to the configuration's resends */
    double speed_ref_rpm;      /* the speed reference in force at the end [rpm] */
    double tap_t;              /* the last period started: t [s] and index (the frame tap after the loop) */
    uint32_t tap_seq;
    int64_t ring_waits;        /* times the loop waited for Python to hand back a slot */
    int64_t wall_ns;           /* wall time of the loop [ns] */
    /* real-time set-up: 0 ok / not asked, else the errno of the refused call */
    int32_t rt_mlock_errno, rt_sched_errno, rt_affinity_errno;
    /* real time: period starts per 1 us lateness bin (nl_late_count: the last bin open-ended), the latest [ns] */
    int64_t late_hist[NL_LATE_BINS];
    int64_t late_max_ns;
    /* real time over a link: wall time of the synchronising period 0, from its start to its Command [ns] (-1: none) */
    int64_t sync_ns;
    /* a shared bus (target_link.shared_bus): frames of ids the target never sends (foreign), frames of its ids that
     * cannot be its own (suspect: a Command for no open seq, a second reply, an implausible FaultTarget); those
     * since the last reply taken and the wall time since it [ns] (the start if none) */
    int64_t bus_foreign_frames, bus_suspect_frames, bus_silent_frames, bus_silent_ns;
    int64_t bus_host_silent;   /* of the foreign frames since the last reply: the host's ids (another node posing as
                                * the host: its Setpoint or ConfigParam reaches the target too) */
} nl_result_t;

typedef struct nl_handle nl_handle_t;

/* Bytes of a handle (the caller allocates it, zeroed, suitably aligned). */
uint64_t nl_handle_size(void);
/* Initialise the handle's synchronisation; 0 ok. */
int nl_init(nl_handle_t *h);
void nl_destroy(nl_handle_t *h);
nl_config_t *nl_config(nl_handle_t *h);
nl_slot_t *nl_slot(nl_handle_t *h, int32_t i);
const nl_result_t *nl_result(const nl_handle_t *h);

/* Run the whole loop (call from the loop's own thread); returns when the run ended. */
void nl_run(nl_handle_t *h);
/* Wait up to timeout_ns for slot i to be full: 1 full, 0 timeout, -1 the run ended with no more slots. */
int nl_wait_full(nl_handle_t *h, int32_t i, int64_t timeout_ns);
/* Hand slot i back to the loop (its noise refilled). */
void nl_release(nl_handle_t *h, int32_t i);
/* Ask the loop to end at the next period (NL_END_INTERRUPTED). */
void nl_stop(nl_handle_t *h);

#endif
