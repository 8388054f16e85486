/* DSVM family: vector and region tables (Figs. 6 and 8), Tables 1 and 2, sequences, candidate
 * counts, the full-set miss diagnostic, the DBCC triangle and SVPWM. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fw_check.h"
#include "fw_fixture.h"
#include "hil_fw_dbcc_mpc.h"
#include "hil_fw_dsvm.h"
#include "hil_fw_fcs_mpc.h"
#include "hil_fw_foc.h"

#define DEG (HIL_FW_PI_F / 180.0f)

/* alpha/beta (per lattice step) of DSVM vector idx */
static void vec_ab(uint8_t idx, float *a, float *b)
{
    const float m = (float)hil_fw_dsvm_vectors[idx].m;
    const float n = (float)hil_fw_dsvm_vectors[idx].n;
    *a = m + 0.5f * n;
    *b = 0.86602540378f * n;
}

/* 1 if angle of (a, b) lies in [lo, hi] deg (mod 360) with a small tolerance */
static int angle_in(float a, float b, float lo, float hi)
{
    float ang = atan2f(b, a) / DEG;
    float x;
    x = ang - lo;
    while (x < -0.01f) {
        x += 360.0f;
    }
    while (x >= 360.0f - 0.01f) {
        x -= 360.0f;
    }
    return x <= hi - lo + 0.01f || fabsf(x - 360.0f) < 0.01f;
}

static int in_list(const uint8_t *list, int n, uint8_t v)
{
    int i;
    for (i = 0; i < n; ++i) {
        if (list[i] == v) {
            return 1;
        }
    }
    return 0;
}

static void test_vectors(void)
{
    /* lattice coordinates of the real vectors (index 0 = zero) */
    static const int lm[7] = {0, 2, 0, -2, -2, 0, 2};
    static const int ln[7] = {0, 0, 2, 2, 0, -2, -2};
    int i;
    int j;
    for (i = 0; i < HIL_FW_DSVM_VECTORS; ++i) {
        const hil_fw_dsvm_vector_t *v = &hil_fw_dsvm_vectors[i];
        CHECK(2 * v->m == lm[v->half_a] + lm[v->half_b] && 2 * v->n == ln[v->half_a] + ln[v->half_b],
              "vector %d is the mean of its halves", i);
        CHECK(hil_fw_dsvm_lattice_index[v->m + 2][v->n + 2] == i, "lattice index of vector %d", i);
        for (j = 0; j < i; ++j) {
            CHECK(v->m != hil_fw_dsvm_vectors[j].m || v->n != hil_fw_dsvm_vectors[j].n, "%d and %d distinct", i, j);
        }
    }
    /* eq. (9): 3N^2 + 3N + 2 = 20 for N = 2, with both zero vectors counted: 19 distinct */
    CHECK(3 * 4 + 3 * 2 + 2 == HIL_FW_DSVM_VECTORS + 1, "eq. (9) count");
}

static void test_regions(void)
{
    int r;
    int i;
    for (r = 0; r < 6; ++r) {
        for (i = 0; i < HIL_FW_DSVM_VECTORS; ++i) {
            float a;
            float b;
            int tri;
            int kite;
            vec_ab((uint8_t)i, &a, &b);
            /* Fig. 6: closed triangle 0, u_{r+1}, u_{r+2} = angle in [60 r, 60 r + 60] */
            tri = i == 0 || angle_in(a, b, 60.0f * (float)r, 60.0f * (float)r + 60.0f);
            /* Fig. 8: closed kite centred on u_{r+1} = angle within 30 deg of 60 r */
            kite = i == 0 || angle_in(a, b, 60.0f * (float)r - 30.0f, 60.0f * (float)r + 30.0f);
            CHECK(tri == in_list(hil_fw_dsvm_triangle[r], 6, (uint8_t)i), "triangle %d vs vector %d", r, i);
            CHECK(kite == in_list(hil_fw_dsvm_kite[r], 5, (uint8_t)i), "kite %d vs vector %d", r, i);
        }
        /* the reference vector leads its own list */
        CHECK(hil_fw_dsvm_triangle[r][0] == 7 + r, "triangle %d reference u_{r,r+1}", r);
        CHECK(hil_fw_dsvm_kite[r][0] == 1 + r, "kite %d reference u_r", r);
    }
    /* the paper's examples: u12 -> u12 u1 u2 u1Z u2Z zero; u2 -> u2 u12 u2Z u23 zero */
    {
        static const uint8_t ex1[6] = {7u, 1u, 2u, 13u, 14u, 0u};
        static const uint8_t ex2[5] = {2u, 7u, 14u, 8u, 0u};
        for (i = 0; i < 6; ++i) {
            CHECK(in_list(hil_fw_dsvm_triangle[0], 6, ex1[i]), "Section III-B example %d", i);
        }
        for (i = 0; i < 5; ++i) {
            CHECK(in_list(hil_fw_dsvm_kite[1], 5, ex2[i]), "Section III-C example %d", i);
        }
    }
}

/* name of a DSVM vector as the paper writes it: "12", "3", "1Z", "0" */
static void vec_name(uint8_t idx, char *buf)
{
    const hil_fw_dsvm_vector_t *v = &hil_fw_dsvm_vectors[idx];
    if (v->half_a == 0u) {
        strcpy(buf, "0");
    } else if (v->half_b == v->half_a) {
        sprintf(buf, "%u", (unsigned)v->half_a);
    } else if (v->half_b == 0u) {
        sprintf(buf, "%uZ", (unsigned)v->half_a);
    } else {
        sprintf(buf, "%u%u", (unsigned)v->half_a, (unsigned)v->half_b);
    }
}

static void test_tables(void)
{
    /* Tables 1 and 2 as printed, rows (h_psi, h_te) = (1,1), (1,0), (0,1), (0,0) */
    static const char *t1[4][6] = {{"12", "23", "34", "45", "56", "61"}, {"56", "61", "12", "23", "34", "45"},
                                   {"23", "34", "45", "56", "61", "12"}, {"45", "56", "61", "12", "23", "34"}};
    static const char *t2[4][6] = {{"2", "3", "4", "5", "6", "1"}, {"6", "1", "2", "3", "4", "5"},
                                   {"3", "4", "5", "6", "1", "2"}, {"5", "6", "1", "2", "3", "4"}};
    static const uint8_t hp[4] = {1u, 1u, 0u, 0u};
    static const uint8_t ht[4] = {1u, 0u, 1u, 0u};
    int row;
    int sct;
    char name[8];
    int cells = 0;
    for (row = 0; row < 4; ++row) {
        for (sct = 1; sct <= 6; ++sct) {
            vec_name(hil_fw_fcs_lookup(HIL_FW_FCS_TABLE_VIRTUAL, hp[row], ht[row], (uint8_t)sct), name);
            CHECK(strcmp(name, t1[row][sct - 1]) == 0, "Table 1 row %d S=%d: got u%s", row, sct, name);
            vec_name(hil_fw_fcs_lookup(HIL_FW_FCS_TABLE_REAL, hp[row], ht[row], (uint8_t)sct), name);
            CHECK(strcmp(name, t2[row][sct - 1]) == 0, "Table 2 row %d S=%d: got u%s", row, sct, name);
            cells += 2;
        }
    }
    CHECK(cells == 48, "24 cells in each table");
    CHECK(hil_fw_fcs_lookup(HIL_FW_FCS_TABLE_REAL, 1u, 1u, 0u) == 255u, "sector 0 rejected");
    CHECK(hil_fw_fcs_lookup(HIL_FW_FCS_TABLE_REAL, 1u, 1u, 7u) == 255u, "sector 7 rejected");
    CHECK(hil_fw_fcs_lookup(3, 1u, 1u, 1u) == 255u, "table 3 rejected");
    /* sector S = 1 centred on u1: [-30, 30) deg */
    {
        static const float ang[8] = {-29.0f, 0.0f, 29.0f, 31.0f, 89.0f, 91.0f, 179.0f, -91.0f};
        static const uint8_t want[8] = {1u, 1u, 1u, 2u, 2u, 3u, 4u, 5u};
        int i;
        for (i = 0; i < 8; ++i) {
            CHECK(hil_fw_fcs_sector(cosf(ang[i] * DEG), sinf(ang[i] * DEG)) == want[i], "sector of %g deg",
                  (double)ang[i]);
        }
    }
    /* a NaN flux estimate: sector 1, never a NaN cast to int (a sector outside 1..6 would index past the
     * tables); an infinite component still has a direction (atan2) and a sector in 1..6 */
    {
        const float inf[2] = {INFINITY, -INFINITY};
        uint8_t sa;
        uint8_t sb;
        int i;
        CHECK(hil_fw_fcs_sector_rot(NAN, 1.0f, 3u) == 1u, "sector of a NaN alpha");
        CHECK(hil_fw_fcs_sector_rot(0.5f, NAN, 0u) == 1u, "sector of a NaN beta");
        for (i = 0; i < 2; ++i) {
            sa = hil_fw_fcs_sector_rot(inf[i], 1.0f, 3u);
            sb = hil_fw_fcs_sector_rot(inf[i], inf[1 - i], 7u);
            CHECK(sa >= 1u && sa <= 6u && sb >= 1u && sb <= 6u, "sectors with %g: %u %u", (double)inf[i],
                  (unsigned)sa, (unsigned)sb);
        }
    }
}

static void test_sequences(void)
{
    uint8_t idx;
    uint8_t prev;
    hil_fw_cmd_t cmd;
    for (idx = 0u; idx < HIL_FW_DSVM_VECTORS; ++idx) {
        for (prev = 0u; prev < 8u; ++prev) {
            float ua;
            float ub;
            float a;
            float b;
            hil_fw_dsvm_sequence(idx, prev, 100001u, &cmd);
            CHECK(cmd.n_states == 2u && cmd.durations_ns[0] + cmd.durations_ns[1] == 100001u, "two halves");
            hil_fw_cmd_mean_voltage_ab(cmd.states, cmd.durations_ns, 2u, 300.0f, &ua, &ub);
            vec_ab(idx, &a, &b);
            CHECK_NEAR(ua, 100.0f * a, 0.01f, "sequence mean alpha");
            CHECK_NEAR(ub, 100.0f * b, 0.01f, "sequence mean beta");
            CHECK(hil_fw_leg_transitions(cmd.states[0], cmd.states[1]) <= 1u, "one leg between halves (%u)",
                  (unsigned)idx);
            CHECK(hil_fw_leg_transitions(prev, cmd.states[0]) <= hil_fw_leg_transitions(prev, cmd.states[1]),
                  "nearer half first");
        }
    }
}

static void test_candidates_and_miss(void)
{
    static const uint8_t ctrl[4] = {HIL_FW_CTRL_DSVM_20, HIL_FW_CTRL_FCS_MPC_1, HIL_FW_CTRL_FCS_MPC_2,
                                    HIL_FW_CTRL_DBCC_MPC};
    static const uint8_t want[4] = {19u, 6u, 5u, 3u};
    hil_fw_state_t s;
    hil_fw_cmd_t cmd;
    int c;
    int k;
    for (c = 0; c < 4; ++c) {
        hil_fw_init(&s);
        CHECK(hil_fw_select_controller(&s, ctrl[c]) == HIL_FW_OK, "select %d", ctrl[c]);
        (void)hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 7.0f);
        for (k = 0; k < 20; ++k) {
            const float th = 0.047f * (float)k;
            hil_fw_meas_t m = fw_meas_dq((uint16_t)k, 0.0f, 7.0f, th, 157.0f, 311.0f);
            hil_fw_step(&s, &m, (uint64_t)k * 100000u, &cmd);
            CHECK(cmd.candidates == want[c], "controller %d: %u candidates", ctrl[c], (unsigned)cmd.candidates);
            CHECK(cmd.n_states == 2u && cmd.vector_id < HIL_FW_DSVM_VECTORS, "two-half command");
            if (ctrl[c] == HIL_FW_CTRL_DSVM_20) {
                CHECK(hil_fw_dsvm_full_miss(&s) == HIL_FW_DSVM_NO_DIAG, "dsvm-20 has no restricted set");
            } else {
                CHECK(hil_fw_dsvm_full_miss(&s) <= 1u, "diagnostic computed");
            }
        }
    }
    /* miss computation on a hand-made candidate list */
    hil_fw_init(&s);
    (void)hil_fw_select_controller(&s, HIL_FW_CTRL_FCS_MPC_1);
    (void)hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 7.0f);
    {
        hil_fw_meas_t m = fw_meas_dq(0u, 0.0f, 7.0f, 0.3f, 157.0f, 311.0f);
        hil_fw_step(&s, &m, 0u, &cmd);
    }
    {
        hil_fw_dsvm_state_t *st = &s.ctrl.dsvm;
        uint8_t best = 0u;
        uint8_t i;
        for (i = 1u; i < HIL_FW_DSVM_VECTORS; ++i) {
            if (hil_fw_dsvm_cost(st, i) < hil_fw_dsvm_cost(st, best)) {
                best = i;
            }
        }
        st->cand[0] = best;
        st->n_cand = 1u;
        hil_fw_dsvm_choose(&s, &cmd);
        CHECK(hil_fw_dsvm_full_miss(&s) == 0u, "optimum in the list: no miss");
        st->cand[0] = best == 0u ? 1u : 0u;
        hil_fw_dsvm_choose(&s, &cmd);
        CHECK(hil_fw_dsvm_full_miss(&s) == 1u, "optimum excluded: miss");
        s.enable = 0u;
        CHECK(hil_fw_dsvm_full_miss(&s) == HIL_FW_DSVM_NO_DIAG, "disabled: no diagnostic");
    }
}

/* One fcs step of controller ctrl with reading bits `reading` (torque mode, 7 N*m reference) from the
 * rotor-frame currents at the angle that puts the current-model flux at psi_deg; `applied` is the
 * switching code applied over [k, k+1). Returns the DSVM state. */
static const hil_fw_dsvm_state_t *fcs_step(hil_fw_state_t *s, uint8_t ctrl, float reading, float band, float iq,
                                           float psi_deg, float omega_m, uint8_t applied)
{
    hil_fw_cmd_t cmd;
    const float delta = atan2f(0.014f * iq, 0.21f); /* flux angle ahead of d at id = 0 */
    hil_fw_meas_t m;
    hil_fw_init(s);
    (void)hil_fw_select_controller(s, ctrl);
    CHECK(hil_fw_set_param(s, HIL_FW_P_FCS_READING, reading) == HIL_FW_OK, "fcs_reading %g", (double)reading);
    (void)hil_fw_set_param(s, HIL_FW_P_TORQUE_BAND, band);
    (void)hil_fw_set_setpoint(s, 1u, HIL_FW_MODE_TORQUE, 7.0f);
    fw_set_applied(s, applied);
    m = fw_meas_dq(0u, 0.0f, iq, psi_deg * DEG - delta, omega_m, 311.0f);
    hil_fw_step(s, &m, 0u, &cmd);
    CHECK(cmd.candidates == (ctrl == HIL_FW_CTRL_FCS_MPC_1 ? 6u : 5u), "candidate count");
    CHECK(s->ctrl.dsvm.cand[0] == s->ctrl.dsvm.ref_vector, "region of the reference vector");
    CHECK(s->ctrl.dsvm.ref_vector == hil_fw_fcs_lookup(ctrl == HIL_FW_CTRL_FCS_MPC_1 ? HIL_FW_FCS_TABLE_VIRTUAL
                                                                                      : HIL_FW_FCS_TABLE_REAL,
                                                       s->ctrl.dsvm.h_psi, s->ctrl.dsvm.h_te, s->ctrl.dsvm.sector),
          "reference vector from the table");
    return &s->ctrl.dsvm;
}

static void test_fcs_readings(void)
{
    hil_fw_state_t s;
    const hil_fw_dsvm_state_t *st;
    uint8_t v0;
    int r;
    /* parameter range: integer 0..255 with the rotation field 0..11 */
    hil_fw_init(&s);
    CHECK(hil_fw_set_param(&s, HIL_FW_P_FCS_READING, 0.0f) == HIL_FW_OK, "default reading accepted");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_FCS_READING, 12.0f) == HIL_FW_E_PARAM_VALUE, "rotation 12 rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_FCS_READING, 256.0f) == HIL_FW_E_PARAM_VALUE, "256 rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_FCS_READING, 1.5f) == HIL_FW_E_PARAM_VALUE, "fraction rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_FCS_READING, 251.0f) == HIL_FW_OK, "all bits, rotation 11");
    /* bits 0-3: S = 1 spans [-30 + 30 r, 30 + 30 r) deg */
    for (r = 0; r < 12; ++r) {
        const float lo = -30.0f + 30.0f * (float)r;
        CHECK(hil_fw_fcs_sector_rot(cosf((lo + 1.0f) * DEG), sinf((lo + 1.0f) * DEG), (uint8_t)r) == 1u,
              "rotation %d: start of S = 1", r);
        CHECK(hil_fw_fcs_sector_rot(cosf((lo + 59.0f) * DEG), sinf((lo + 59.0f) * DEG), (uint8_t)r) == 1u,
              "rotation %d: end of S = 1", r);
        CHECK(hil_fw_fcs_sector_rot(cosf((lo + 61.0f) * DEG), sinf((lo + 61.0f) * DEG), (uint8_t)r) == 2u,
              "rotation %d: S = 2 next", r);
        CHECK(hil_fw_fcs_sector_rot(cosf((lo - 1.0f) * DEG), sinf((lo - 1.0f) * DEG), (uint8_t)r) == 6u,
              "rotation %d: S = 6 before", r);
    }
    /* flux at 15 deg: S = 1 (r = 0), 1 (r = 1, [0, 60)), 2 (r = 11, S = 1 is [-60, 0)), 6 (r = 2) */
    {
        static const float rot[4] = {0.0f, 1.0f, 11.0f, 2.0f};
        static const uint8_t sector[4] = {1u, 1u, 2u, 6u};
        /* Table 1 row (h_psi 1, h_te 1) of those sectors: u12, u12, u23, u61 */
        static const uint8_t ref[4] = {7u, 7u, 8u, 12u};
        int i;
        for (i = 0; i < 4; ++i) {
            st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_1, rot[i], 0.2f, 6.0f, 15.0f, 0.0f, 0u);
            CHECK(st->sector == sector[i], "rotation %g: sector %u", (double)rot[i], (unsigned)st->sector);
            CHECK(st->h_psi == 1u && st->h_te == 1u, "rotation %g: flux and torque below the references",
                  (double)rot[i]);
            CHECK(st->ref_vector == ref[i], "rotation %g: reference vector %u", (double)rot[i],
                  (unsigned)st->ref_vector);
        }
    }
    /* bit 4: u3 (120 deg) applied over [k, k+1) turns the flux from 28 deg (S = 1) past 30 deg (S = 2)
     * by k+1; at k it is still in S = 1 */
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_2, 0.0f, 0.2f, 6.0f, 28.0f, 0.0f, 2u);
    CHECK(st->sector == 2u, "k+1: flux past 30 deg (S = %u)", (unsigned)st->sector);
    v0 = st->ref_vector;
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_2, (float)HIL_FW_FCS_AT_K, 0.2f, 6.0f, 28.0f, 0.0f, 2u);
    CHECK(st->sector == 1u, "k: flux at 28 deg (S = %u)", (unsigned)st->sector);
    CHECK_NEAR(st->psi_mag1, sqrtf(0.21f * 0.21f + 0.084f * 0.084f), 1e-5f, "k: |psi(k)| of the current model");
    CHECK(st->ref_vector != v0, "k vs k+1: other reference vector");
    /* bit 5: torque 0.77 N*m above the reference: h_te 0 without band, kept at 1 inside +-1 N*m */
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_1, 0.0f, 1.0f, 8.5f, 0.0f, 0.0f, 0u);
    CHECK(st->te1 > 7.5f && st->te1 < 8.0f && st->h_te == 0u, "no band: decrease (te1 %g)", (double)st->te1);
    v0 = st->ref_vector;
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_1, (float)HIL_FW_FCS_TORQUE_BAND, 1.0f, 8.5f, 0.0f, 0.0f, 0u);
    CHECK(st->h_te == 1u && st->ref_vector != v0, "band 1 N*m: torque comparator stays at 1");
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_1, (float)HIL_FW_FCS_TORQUE_BAND, 0.5f, 8.5f, 0.0f, 0.0f, 0u);
    CHECK(st->h_te == 0u, "band 0.5 N*m: 0.77 N*m above switches to decrease");
    /* bit 6: |psi| = 0.226 Wb lies between psi_f = 0.21 Wb and the reference flux 0.234 Wb */
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_1, 0.0f, 0.2f, 6.0f, 0.0f, 0.0f, 0u);
    CHECK(st->h_psi == 1u && st->psi_ref > 0.233f, "flux of the current references: increase");
    v0 = st->ref_vector;
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_1, (float)HIL_FW_FCS_FLUX_PSI_F, 0.2f, 6.0f, 0.0f, 0.0f, 0u);
    CHECK(st->h_psi == 0u && st->psi_ref == 0.21f && st->ref_vector != v0, "psi_f reference: decrease");
    hil_fw_init(&s);
    /* bit 7: torque below the reference gives h_te 0 */
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_1, 0.0f, 0.2f, 6.0f, 0.0f, 0.0f, 0u);
    CHECK(st->h_te == 1u, "torque below the reference: increase");
    v0 = st->ref_vector;
    st = fcs_step(&s, HIL_FW_CTRL_FCS_MPC_1, (float)HIL_FW_FCS_TORQUE_INVERT, 0.2f, 6.0f, 0.0f, 0.0f, 0u);
    CHECK(st->h_te == 0u && st->ref_vector != v0, "inverted sign: decrease");
}

static void test_dbcc_triangle(void)
{
    uint8_t out[3];
    int i;
    /* a point just off u12 = (1, 1): the triangle holds u12 */
    hil_fw_dbcc_triangle(1.1f, 0.8f, out);
    CHECK(in_list(out, 3, 7u), "u12 among the corners");
    /* far outside the hexagon along u1: clamped, corners inside */
    hil_fw_dbcc_triangle(50.0f, 0.1f, out);
    for (i = 0; i < 3; ++i) {
        CHECK(out[i] < HIL_FW_DSVM_VECTORS, "corner %d inside", i);
    }
    CHECK(in_list(out, 3, 1u), "u1 among the clamped corners");
    hil_fw_dbcc_triangle(NAN, 0.0f, out);
    CHECK(in_list(out, 3, 0u), "NaN falls back to the zero vector's triangle");
}

static void test_svpwm(void)
{
    int deg;
    for (deg = -175; deg < 180; deg += 10) {
        const float ang = (float)deg * DEG;
        const float ua = 120.0f * cosf(ang);
        const float ub = 120.0f * sinf(ang);
        uint8_t a;
        uint8_t b;
        uint32_t t[3];
        uint8_t st[3];
        float ma;
        float mb;
        (void)hil_fw_svpwm(ua, ub, 311.0f, 100000u, &a, &b, t);
        st[0] = a;
        st[1] = b;
        st[2] = 7u;
        CHECK(t[0] + t[1] + t[2] == 100000u, "dwell times sum to Ts");
        CHECK(hil_fw_leg_transitions(0u, a) == 1u && hil_fw_leg_transitions(a, b) == 1u &&
                  hil_fw_leg_transitions(b, 7u) == 1u,
              "0-a-b-7 one leg at a time (%d deg)", deg);
        hil_fw_cmd_mean_voltage_ab(st, t, 3u, 311.0f, &ma, &mb);
        CHECK_NEAR(ma, ua, 0.2f, "svpwm mean alpha");
        CHECK_NEAR(mb, ub, 0.2f, "svpwm mean beta");
    }
    {   /* a NaN or infinite reference: zero vector over Ts, never a NaN cast */
        const float bad[3] = {NAN, INFINITY, -INFINITY};
        int i;
        for (i = 0; i < 3; ++i) {
            uint8_t a;
            uint8_t b;
            uint32_t t[3];
            (void)hil_fw_svpwm(bad[i], 10.0f, 311.0f, 100000u, &a, &b, t);
            CHECK(t[0] == 0u && t[1] == 0u && t[2] == 100000u, "svpwm of %g: %u %u %u", (double)bad[i],
                  (unsigned)t[0], (unsigned)t[1], (unsigned)t[2]);
        }
    }
}

int main(void)
{
    test_vectors();
    test_regions();
    test_tables();
    test_sequences();
    test_candidates_and_miss();
    test_fcs_readings();
    test_dbcc_triangle();
    test_svpwm();
    return FW_REPORT("test_dsvm");
}
