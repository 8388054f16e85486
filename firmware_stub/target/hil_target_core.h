/*
 * The portable HIL target core: frames in, frames out. Implements the target behaviour of
 * docs/protocol.md ("Target behaviour") exactly as the Python virtual target (src/pmsm_hil/sim_target/target.py)
 * does, on top of the generated codec (firmware_stub/generated/hil_protocol.c), and calls the
 * firmware API (hil_app.h). Boards feed received frames to hil_core_rx and send what hil_core_tx
 * returns; the SIL shared library exports the same functions to the host.
 */
#ifndef HIL_TARGET_CORE_H
#define HIL_TARGET_CORE_H

#include <stdint.h>

#include "hil_app.h"

#define HIL_CORE_MAX_PAYLOAD 64
#define HIL_CORE_TX_QUEUE 8
#define HIL_CORE_NODE 1

typedef struct {
    uint32_t id;                          /* 11-bit arbitration id */
    uint8_t len;                          /* payload length */
    uint8_t fd;                           /* 1: CAN FD frame */
    uint8_t data[HIL_CORE_MAX_PAYLOAD];
} hil_core_frame_t;

typedef struct {
    uint32_t frames_rx;
    uint32_t measurements;
    uint32_t commands;
    uint32_t config_writes;
    uint32_t config_rejected;
    uint32_t faults;
    uint32_t unknown_id;
    uint32_t bad_length;
    uint32_t tx_overflow;
    uint32_t steps;
} hil_core_counters_t;

/* Reset the core (disabled, controller off, Ts 100 us) and call hil_app_init. */
void hil_core_init(void);

/* One received frame; replies are queued for hil_core_tx. */
void hil_core_rx(uint32_t id, const uint8_t *data, uint8_t len, uint8_t fd);

/* Next reply frame into *out: 1, or 0 when none is queued. */
int hil_core_tx(hil_core_frame_t *out);

const hil_core_counters_t *hil_core_counters(void);

/* The last command hil_app_step produced (debug outputs included) and its measured execution time [ns]. */
const hil_app_cmd_t *hil_core_last_cmd(void);
uint32_t hil_core_last_exec_ns(void);

/* Step markers: called right before and right after hil_app_step (never inlined); an instruction
 * counter (the QEMU plugin) counts what runs between them. The core calls the pair once with nothing
 * between at init: the markers' own cost. */
void hil_core_step_begin(void);
void hil_core_step_end(void);

/* Board hooks, implemented by the board layer (host: boards/host/hil_sil.c, MCU: boards/<board>/):
 * a free-running clock and the execution time [ns] between two of its readings. */
uint32_t hil_board_clock(void);
uint32_t hil_board_exec_ns(uint32_t t0, uint32_t t1);

#endif
