/*
 * Reference firmware: reference-vector stage of the proposed FCS-MPC I and II (Section III-B/C):
 * stator flux from eq. (10) in the stator frame, torque from eq. (11), two two-level comparators
 * without band, flux sector S (S = 1 centred on u1, [-30, 30) deg), Tables 1 and 2, then the
 * region of Fig. 6 (I, 6 candidates) or Fig. 8 (II, 5 candidates) of the chosen reference vector.
 * Flux and torque are compared at k+1 (delay-compensated, as the two-step prediction).
 * Parameter fcs_reading (HIL_FW_P_FCS_READING) selects other readings of the text for the experiments
 * of docs/comparisons/niu2020.md (bit flags below). Its power-on value is the sentinel
 * HIL_FW_FCS_READING_CONTROLLER_DEFAULT, resolved at every step by the selected controller: fcs-mpc-1
 * reading 11 (sectors centred on the virtual vectors, under which Table 1 is the classic DTC table),
 * fcs-mpc-2 reading 0 (the reading above). Resolving per step, not when the controller is selected,
 * makes the result independent of the order of ConfigParam and Setpoint frames.
 * See docs/algorithms/fcs_mpc_regions.md.
 */
#ifndef HIL_FW_FCS_MPC_H
#define HIL_FW_FCS_MPC_H

#include <stdint.h>

struct hil_fw_state;

#define HIL_FW_FCS_TABLE_VIRTUAL 1 /* Table 1: reference among u12..u61 */
#define HIL_FW_FCS_TABLE_REAL 2    /* Table 2: reference among u1..u6 */

/* fcs_reading bits. Bits 0-3: sector rotation r = 0..11, S = 1 spans [-30 + 30 r, 30 + 30 r) deg
 * (r = 0: centred on u1; r = 1: [0, 60); r = 11: [-60, 0); r = 2: the table shifted by one column). */
#define HIL_FW_FCS_ROT_MASK 15u
#define HIL_FW_FCS_AT_K 16u          /* flux and torque compared at k (psi(k), i(k)) instead of k+1 */
#define HIL_FW_FCS_TORQUE_BAND 32u   /* torque comparator with hysteresis band +-torque_band [N*m] */
#define HIL_FW_FCS_FLUX_PSI_F 64u    /* flux reference flux_ref if > 0, else psi_f (Table 3 "stator flux") */
#define HIL_FW_FCS_TORQUE_INVERT 128u /* torque comparator sign inverted (h_te = 1 when T_ref < T) */

/* Power-on value of fcs_reading: "the selected controller's default" (rotation field 15, no flags). Not
 * accepted as a ConfigParam (rotation fields 12-15 are rejected): send 11 or 0 to choose explicitly.
 * Defaults (docs/algorithms/fcs_mpc_regions.md, "Defaults"): fcs-mpc-1 holds speed and torque over the
 * operating range only with 11; 11 makes fcs-mpc-2 worse at every point, so it keeps 0. */
#define HIL_FW_FCS_READING_CONTROLLER_DEFAULT 15u
#define HIL_FW_FCS_READING_DEFAULT_1 11u /* fcs-mpc-1: r = 11, comparators as the text defines them */
#define HIL_FW_FCS_READING_DEFAULT_2 0u  /* fcs-mpc-2: r = 0, the reading as built */

/* Tables 1 and 2 as printed: rows (h_psi, h_te) = (1,1), (1,0), (0,1), (0,0); columns S = 1..6;
 * entries are DSVM vector indices (hil_fw_dsvm.h). */
extern const uint8_t hil_fw_fcs_table1[4][6];
extern const uint8_t hil_fw_fcs_table2[4][6];

/* Sector S (1..6) of a stator-frame vector: S = 1 for angles in [-30, 30) deg. */
uint8_t hil_fw_fcs_sector(float alpha, float beta);

/* Sector S (1..6) with the boundaries rotated by rot * 30 deg (rot 0..11): S = 1 for angles in
 * [-30 + 30 rot, 30 + 30 rot) deg; 1 for a non-finite vector (NaN flux estimate), never out of 1..6. */
uint8_t hil_fw_fcs_sector_rot(float alpha, float beta, uint8_t rot);

/* Reference vector (DSVM index) of table 1 or 2 for comparator outputs and sector S (1..6);
 * 255 for a bad argument. */
uint8_t hil_fw_fcs_lookup(int table, uint8_t h_psi, uint8_t h_te, uint8_t sector);

/* fcs_reading in effect for the selected controller (the sentinel resolved, other values unchanged). */
unsigned hil_fw_fcs_reading(const struct hil_fw_state *s);

/* Reference stages of fcs-mpc-1 and fcs-mpc-2: fill the candidate list of the DSVM state. */
void hil_fw_fcs_mpc1_reference(struct hil_fw_state *s);
void hil_fw_fcs_mpc2_reference(struct hil_fw_state *s);

#endif
