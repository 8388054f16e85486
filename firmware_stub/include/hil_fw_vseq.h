/*
 * Reference firmware: symmetric switching sequences of up to two adjacent active vectors and a
 * zero vector (3vmpc, hv-mpfc), their zero-vector choice, their packing into the command slots and
 * pulse-based dead-time compensation. See docs/algorithms/hv_mpfc.md.
 *
 * A sequence is "nested": the outermost state is split into two halves at both ends of the period,
 * the next one likewise inside, the innermost is applied once in the middle, e.g.
 * Z/2 - A/2 - B - A/2 - Z/2 for the nesting (Z, A, B).
 */
#ifndef HIL_FW_VSEQ_H
#define HIL_FW_VSEQ_H

#include <stdint.h>

#define HIL_FW_VSEQ_MAX 5 /* sub-intervals of the longest symmetric sequence */

/* Zero-vector rules (param zero_select). */
#define HIL_FW_ZERO_PAPER 0u           /* zero adjacent to the longer active vector (Section 3.2) */
#define HIL_FW_ZERO_MIN_TRANSITIONS 1u /* fewest leg transitions incl. the period boundary */

typedef struct {
    uint8_t n;                             /* sub-intervals used, 2 * nest - 1 */
    uint8_t nest;                          /* distinct states, outermost first, 1..3 */
    uint8_t states[HIL_FW_VSEQ_MAX];       /* switching codes 4*Sa + 2*Sb + Sc */
    uint32_t durations_ns[HIL_FW_VSEQ_MAX];/* lengths [ns] */
} hil_fw_vseq_t;

/* Dwell times of one period: the longer active vector u_opt1, the shorter u_opt2 (switching codes
 * of adjacent vectors) and the zero vector [ns]; zero times mean "not applied". */
typedef struct {
    uint8_t v_long;
    uint8_t v_short;
    uint32_t t_long_ns;
    uint32_t t_short_ns;
    uint32_t t_zero_ns;
} hil_fw_dwell_t;

/* Nested symmetric sequence of n (1..3) distinct states, outermost first; times are each state's
 * total [ns]. Outer states are halved (the first half gets the smaller ns when odd); states with
 * zero time are left out, an outer state shorter than 2 ns is left out and its time given to the
 * innermost state, so the sum of the times is kept. */
void hil_fw_vseq_nest(hil_fw_vseq_t *q, const uint8_t *states, const uint32_t *times_ns, uint8_t n);

/* The symmetric sequence of dwell times d with the zero-vector rule zero_select (HIL_FW_ZERO_*).
 * fold != 0: the sequence will be sent folded (see hil_fw_vseq_pack) with parity odd; the
 * min-transitions rule then scores the folded form. prev_code: last state of the previous command. */
void hil_fw_vseq_plan(hil_fw_vseq_t *q, const hil_fw_dwell_t *d, uint8_t zero_select, uint8_t prev_code,
                      uint8_t fold, uint8_t odd);

/* Copy a sequence into command slots. fold == 0: unchanged (needs max_slots >= q->n; 0 returned
 * otherwise). fold != 0: the distinct states of the first half, each with its whole time, in
 * sequence order on even periods (odd == 0) and reversed on odd ones; two periods then form the
 * symmetric sequence of a 2*Ts carrier. Returns the slots used. */
uint8_t hil_fw_vseq_pack(const hil_fw_vseq_t *q, uint8_t fold, uint8_t odd, uint8_t max_slots, uint8_t *states,
                         uint32_t *durations_ns);

/* Copy a sequence into command slots to be sent with the mirror flag: its q->nest distinct states,
 * outermost first, with the durations of the first half; the innermost slot gets the rest, so that
 * 2*(d0+..+d(nest-2)) + d(nest-1) = the sequence's total (an odd total of an outer state loses its
 * odd ns to the innermost one). Returns the slots used, 0 if max_slots < q->nest. */
uint8_t hil_fw_vseq_pack_mirror(const hil_fw_vseq_t *q, uint8_t max_slots, uint8_t *states, uint32_t *durations_ns);

/* The sequence the plant applies for command slots (states, durations_ns, n): unchanged, or with
 * mirror != 0 s0..s(n-1) then s(n-2)..s0 with the same durations. out_*: room for 2n - 1 entries.
 * Returns the length written. */
uint8_t hil_fw_vseq_expand(const uint8_t *states, const uint32_t *durations_ns, uint8_t n, uint8_t mirror,
                           uint8_t *out_states, uint32_t *out_durations_ns);

/* Leg transitions from prev_code through the n states (the boundary one included). */
uint8_t hil_fw_vseq_transitions(uint8_t prev_code, const uint8_t *states, uint8_t n);

/* Pulse-based dead-time compensation: every edge inside the period that the inverter delays by
 * the dead time (rising edge with the phase current i > 0, out of the leg; falling edge with
 * i < 0) is moved t_dead_ns earlier, within the period. i_abc [A]: phase currents at the edges.
 * The sum of the durations is unchanged. Returns the number of edges moved. */
uint8_t hil_fw_vseq_dt_comp(const uint8_t *states, uint32_t *durations_ns, uint8_t n, const float *i_abc,
                            uint32_t t_dead_ns);

/* Dead-time compensation of mirrored command slots (see hil_fw_vseq_pack_mirror), symmetric: an
 * edge between slots j and j+1 and its mirror image form one leg pulse, and exactly one of the two
 * is delayed by the inverter, so the leg's high time per period is short by sign(i)*t_dead. Both
 * edges move by t_dead/2 (the inward edge by d_j -/+ t_dead/2, the mirrored one the other way) so the
 * leg's high time grows by sign(i)*t_dead: an inward rising edge moves earlier for i > 0 and later
 * for i < 0, an inward falling edge the reverse. An edge where several legs flip moves only if they
 * agree; moves are clamped so no slot becomes negative. Returns the number of edges moved. */
uint8_t hil_fw_vseq_dt_comp_mirror(const uint8_t *states, uint32_t *durations_ns, uint8_t n, const float *i_abc,
                                   uint32_t t_dead_ns);

#endif
