/*
 * The in-process link of the native loop: the C target core (firmware_stub/target/hil_target_core.c) and the
 * reference firmware behind it, reached as an ordinary nl_link_t. `send` hands a frame to the core
 * (hil_core_rx: a Measurement steps the firmware at once), `recv` takes the core's next queued reply
 * (hil_core_tx) and never waits: the core answers inside `send`, so nothing arrives later (NL_LINK_IN_PROCESS).
 * `diag` says what the reference firmware's profiled step measured (stage split, torque reference, candidate
 * miss), `period` counts the Measurements for a target made silent after `silent_after` of them (a test's fault
 * injection: it then ignores Measurements, as src/pmsm_hil/sim_target/target.py does). The core keeps its
 * state in C globals: one such link per process at a time (src/pmsm_hil/hil/runner/core_link.py holds the
 * lock). No allocation.
 */
#ifndef HIL_NATIVE_LINK_CORE_H
#define HIL_NATIVE_LINK_CORE_H

#include <stdint.h>

#include "nl_link.h"

typedef struct {
    int64_t silent_after;      /* Measurements the core answers (-1: all); later ones are not delivered */
    int64_t measurements;      /* Measurements sent so far (period starts) */
    nl_link_stats_t stats;     /* frames_tx (every frame sent, delivered or not) and frames_rx */
} nl_core_link_t;

/* Send one frame to the core: 0 (a Measurement of a silent target is counted but not delivered). */
int nl_core_send(nl_core_link_t *s, const hil_core_frame_t *f);

/* The core's next reply into *f: 1; 0 when it has none (whatever the deadline: nothing comes later). */
int nl_core_recv(nl_core_link_t *s, hil_core_frame_t *f, int64_t deadline_ns);

/* *l: the core's link on *s (flags NL_LINK_IN_PROCESS, with diag and period). */
void nl_core_link(nl_link_t *l, nl_core_link_t *s);

#endif
