/*
 * Reference firmware: deadbeat-current-control based MPC (Section II-C): the reference voltage of
 * eq. (6) from the delay-compensated currents, then the three DSVM vectors at the corners of the
 * lattice triangle that contains it (clamped into the hexagon) evaluated with g1.
 * See docs/algorithms/dsvm.md.
 */
#ifndef HIL_FW_DBCC_MPC_H
#define HIL_FW_DBCC_MPC_H

#include <stdint.h>

struct hil_fw_state;

#define HIL_FW_DBCC_CANDIDATES 3

/* Corners (DSVM indices) of the lattice triangle containing lattice point (m, n), after clamping
 * into the hexagon; returns the corner count written to out (3). */
uint8_t hil_fw_dbcc_triangle(float m, float n, uint8_t out[3]);

/* Reference stage of dbcc-mpc. */
void hil_fw_dbcc_reference(struct hil_fw_state *s);

#endif
