/* 3vmpc / hv-mpfc: Table 1, eq. (9) deadbeat, the symmetric sequence, the five modes of Section 3.2,
 * durations, narrow-pulse removal, zero-vector rules, packing and dead-time compensation. */
#include "fw_check.h"
#include "fw_fixture.h"
#include "hil_fw.h"
#include "hil_fw_3vmpc.h"
#include "hil_fw_hv_mpfc.h"
#include "hil_fw_vseq.h"

#define TS_NS 100000u
#define VDC 310.0f

/* Table 2 machine of 003_7bbad73a6f78337e.txt, Ts = 100 us, torque mode. */
static void xiao_fixture(hil_fw_state_t *s, uint8_t controller, float torque, float t_thr)
{
    const fw_param_t machine[] = {
        {HIL_FW_P_RS, 1.2f}, {HIL_FW_P_LD, 0.0085f}, {HIL_FW_P_LQ, 0.0085f}, {HIL_FW_P_PSI_F, 0.175f},
        {HIL_FW_P_POLE_PAIRS, 4.0f}, {HIL_FW_P_VDC, VDC}, {HIL_FW_P_TORQUE_LIMIT, 9.0f}, {HIL_FW_P_T_THR, t_thr},
    };
    const int refused = fw_fixture_machine(s, machine, FW_COUNT(machine), controller, torque);
    CHECK(refused == 0, "machine set-up refused at %d", refused);
}

static uint32_t lcg = 12345u;
static float urand(void)
{
    lcg = lcg * 1664525u + 1013904223u;
    return (float)(lcg >> 8) / 16777216.0f;
}

/* Step with the problem captured just before the prediction stage. */
static void step_capture(hil_fw_state_t *s, const hil_fw_meas_t *m, hil_fw_hv_problem_t *p, hil_fw_cmd_t *c)
{
    hil_fw_stage_measure(s, m, 0u);
    hil_fw_stage_reference(s);
    hil_fw_hv_prepare(s, p);
    hil_fw_stage_predict(s, c);
}

static void mean_voltage(const uint8_t *st, const uint32_t *du, uint8_t n, float *ua, float *ub)
{
    float a = 0.0f;
    float b = 0.0f;
    float tot = 0.0f;
    uint8_t i;
    for (i = 0u; i < n; ++i) {
        float x;
        float y;
        hil_fw_state_voltage_ab(st[i], VDC, &x, &y);
        a += (float)du[i] * x;
        b += (float)du[i] * y;
        tot += (float)du[i];
    }
    *ua = a / tot;
    *ub = b / tot;
}

/* A three-slot sequence under test: its states (codes 4 Sa + 2 Sb + Sc) and its durations [ns]. */
static void set_states(uint8_t *st, uint8_t a, uint8_t b, uint8_t c)
{
    st[0] = a;
    st[1] = b;
    st[2] = c;
}

static void set_durations(uint32_t *du, uint32_t a, uint32_t b, uint32_t c)
{
    du[0] = a;
    du[1] = b;
    du[2] = c;
}

static uint32_t sum_ns(const uint32_t *du, uint8_t n)
{
    uint32_t t = 0u;
    uint8_t i;
    for (i = 0u; i < n; ++i) {
        t += du[i];
    }
    return t;
}

/* Sum of the applied (mirror-expanded) sequence of a command [ns]. */
static uint32_t cmd_sum(const hil_fw_cmd_t *c)
{
    uint8_t st[HIL_FW_MAX_APPLIED];
    uint32_t du[HIL_FW_MAX_APPLIED];
    const uint8_t n = hil_fw_vseq_expand(c->states, c->durations_ns, c->n_states, c->mirror, st, du);
    return sum_ns(du, n);
}

/* Make the applied command (during [k, k+1)) realise the stator-frame voltage (ua, ub) [V]. */
static void set_applied_voltage(hil_fw_state_t *s, float ua, float ub)
{
    hil_fw_hv_problem_t p = {0};
    hil_fw_hv_pair_t pair;
    p.v_alpha = ua;
    p.v_beta = ub;
    p.vdc = VDC;
    hil_fw_hv_pair_duties(&p, hil_fw_hv_sector(ua, ub), 100.0e-6f, &pair);
    s->applied.n_states = 3u;
    s->applied.states[0] = pair.v1;
    s->applied.states[1] = pair.v2;
    s->applied.states[2] = 0u;
    s->applied.durations_ns[0] = (uint32_t)(pair.d1 * (float)TS_NS + 0.5f);
    s->applied.durations_ns[1] = (uint32_t)(pair.d2 * (float)TS_NS + 0.5f);
    s->applied.durations_ns[2] = TS_NS - s->applied.durations_ns[0] - s->applied.durations_ns[1];
}

static void test_sector_table(void)
{
    /* Table 1 as printed: (first, second) switching codes per sector. */
    static const uint8_t want[6][2] = {{4u, 6u}, {2u, 6u}, {2u, 3u}, {1u, 3u}, {1u, 5u}, {4u, 5u}};
    uint8_t s;
    for (s = 1u; s <= 6u; ++s) {
        uint8_t v1;
        uint8_t v2;
        const float mid = ((float)s - 0.5f) * HIL_FW_PI_F / 3.0f;
        const float lo = ((float)s - 1.0f) * HIL_FW_PI_F / 3.0f + 0.01f;
        const float hi = (float)s * HIL_FW_PI_F / 3.0f - 0.01f;
        hil_fw_hv_table1(s, &v1, &v2);
        CHECK(v1 == want[s - 1u][0] && v2 == want[s - 1u][1], "Table 1 sector %u: got (%u, %u)", s, v1, v2);
        CHECK(hil_fw_hv_sector(cosf(mid), sinf(mid)) == s, "sector of %g rad", (double)mid);
        CHECK(hil_fw_hv_sector(0.3f * cosf(lo), 0.3f * sinf(lo)) == s, "sector near its start, %u", s);
        CHECK(hil_fw_hv_sector(2.0f * cosf(hi), 2.0f * sinf(hi)) == s, "sector near its end, %u", s);
        /* The pair bounds the sector: both vectors within 60 degrees of its middle. */
        {
            float a1;
            float b1;
            hil_fw_state_voltage_ab(v1, VDC, &a1, &b1);
            CHECK((a1 * cosf(mid) + b1 * sinf(mid)) / (2.0f / 3.0f * VDC) > 0.85f, "u1 bounds sector %u", s);
            hil_fw_state_voltage_ab(v2, VDC, &a1, &b1);
            CHECK((a1 * cosf(mid) + b1 * sinf(mid)) / (2.0f / 3.0f * VDC) > 0.85f, "u2 bounds sector %u", s);
        }
    }
    CHECK(hil_fw_hv_sector(1.0f, -1.0e-6f) == 6u, "just below 0 rad is sector 6");
    CHECK(hil_fw_hv_sector(NAN, 1.0f) == 1u && hil_fw_hv_sector(1.0f, NAN) == 1u, "a NaN vector: sector 1");
}

/* hv-mpfc picks the Table 1 pair of the flux error sector, in one prediction. */
static void test_pair_follows_flux_error(void)
{
    hil_fw_state_t s;
    hil_fw_hv_problem_t p;
    hil_fw_cmd_t c;
    int k;
    for (k = 0; k < 24; ++k) {
        const float th = (float)k * 0.27f;
        hil_fw_meas_t m = fw_meas_dq(7u, 0.0f, 2.0f, th, 1000.0f * HIL_FW_PI_F / 30.0f, VDC);
        uint8_t v1;
        uint8_t v2;
        uint8_t sector;
        uint8_t i;
        xiao_fixture(&s, HIL_FW_CTRL_HV_MPFC, 4.0f, 0.0f);
        step_capture(&s, &m, &p, &c);
        sector = hil_fw_hv_sector(p.err_alpha, p.err_beta);
        hil_fw_hv_table1(sector, &v1, &v2);
        CHECK(s.ctrl.hv.sector == sector && c.vector_id % 16u == sector, "sector %u vs %u", s.ctrl.hv.sector,
              sector);
        CHECK(c.candidates == 1u, "hv-mpfc: one prediction, got %u", c.candidates);
        for (i = 0u; i < s.ctrl.hv.seq.n; ++i) {
            const uint8_t x = s.ctrl.hv.seq.states[i];
            CHECK(x == 0u || x == 7u || x == v1 || x == v2, "state %u outside the Table 1 pair", x);
        }
    }
}

/* Eq. (9): the sequence's mean voltage is the deadbeat voltage, and eq. (6) applied with it
 * (independent re-implementation, correct sign of the q cross term) lands on the reference. */
static void test_deadbeat(void)
{
    int infeasible = 0;
    int k;
    for (k = 0; k < 200; ++k) {
        hil_fw_state_t s;
        hil_fw_hv_problem_t p;
        hil_fw_cmd_t c;
        const float rpm = 200.0f + 1800.0f * urand();
        const float wm = rpm * HIL_FW_PI_F / 30.0f;
        const float we = 4.0f * wm;
        const float th = 6.2831853f * urand();
        const float iq = 4.0f / (1.5f * 4.0f * 0.175f) + (urand() - 0.5f) * 0.6f;
        const float id = (urand() - 0.5f) * 0.6f;
        const uint8_t ctrl = (k & 1) ? HIL_FW_CTRL_3VMPC : HIL_FW_CTRL_HV_MPFC;
        const float ts = 100.0e-6f;
        hil_fw_meas_t m = fw_meas_dq((uint16_t)k, id, iq, th, wm, VDC);
        float ua;
        float ub;
        float ud;
        float uq;
        float cm;
        float sm;
        float psid2;
        float psiq2;
        hil_fw_hv_pair_t pair;
        xiao_fixture(&s, ctrl, 4.0f, 0.0f);
        /* The command applied during [k, k+1): the steady-state voltage of the measured currents. */
        {
            const float thm = th + 0.5f * we * ts;
            const float vd = 1.2f * id - we * 0.0085f * iq;
            const float vq = 1.2f * iq + we * (0.0085f * id + 0.175f);
            set_applied_voltage(&s, vd * cosf(thm) - vq * sinf(thm), vd * sinf(thm) + vq * cosf(thm));
        }
        step_capture(&s, &m, &p, &c);
        hil_fw_hv_pair_duties(&p, s.ctrl.hv.sector, ts, &pair);
        if (pair.err2 > 1.0e-12f) {
            ++infeasible; /* beyond the hexagon: no deadbeat solution exists */
            continue;
        }
        CHECK(s.ctrl.hv.mode == HIL_FW_HV_MODE_THREE, "t_thr = 0: three vectors (mode %u)", s.ctrl.hv.mode);
        mean_voltage(s.ctrl.hv.seq.states, s.ctrl.hv.seq.durations_ns, s.ctrl.hv.seq.n, &ua, &ub);
        CHECK_NEAR(ua, p.v_alpha, 0.02f, "mean u_alpha = deadbeat voltage");
        CHECK_NEAR(ub, p.v_beta, 0.02f, "mean u_beta = deadbeat voltage");
        /* eq. (6) from psi(k+1) over [k+1, k+2) with the applied mean voltage. */
        cm = p.cos_m;
        sm = p.sin_m;
        ud = ua * cm + ub * sm;
        uq = -ua * sm + ub * cm;
        psid2 = p.psi_d1 + ts * ud + we * ts * p.psi_q1 - ts * 1.2f * (p.psi_d1 - 0.175f) / 0.0085f;
        psiq2 = p.psi_q1 + ts * uq - we * ts * p.psi_d1 - ts * 1.2f * p.psi_q1 / 0.0085f;
        CHECK_NEAR(psid2, 0.175f + 0.0085f * s.ref.i_d, 2.0e-6f, "psi_d(k+2) = psi_d*");
        CHECK_NEAR(psiq2, 0.0085f * s.ref.i_q, 2.0e-6f, "psi_q(k+2) = psi_q*");
        CHECK(cmd_sum(&c) == TS_NS, "command sums to Ts");
        CHECK(sum_ns(s.ctrl.hv.seq.durations_ns, s.ctrl.hv.seq.n) == TS_NS, "sequence sums to Ts");
    }
    CHECK(infeasible < 20, "most random points have a deadbeat solution (%d of 200 not)", infeasible);
}

/* Mode 1: zero - longer - shorter - longer - zero, four one-leg transitions, zero next to the
 * longer vector (paper rule). */
static void test_symmetric_sequence(void)
{
    int k;
    int checked = 0;
    for (k = 0; k < 300; ++k) {
        hil_fw_state_t s;
        hil_fw_cmd_t c;
        const float th = 6.2831853f * urand();
        hil_fw_meas_t m = fw_meas_dq((uint16_t)k, 0.0f, 3.8f, th, 1000.0f * HIL_FW_PI_F / 30.0f, VDC);
        const hil_fw_vseq_t *q;
        uint8_t i;
        uint8_t flips = 0u;
        xiao_fixture(&s, (k & 1) ? HIL_FW_CTRL_3VMPC : HIL_FW_CTRL_HV_MPFC, 4.0f, 0.0f);
        hil_fw_step(&s, &m, 0u, &c);
        q = &s.ctrl.hv.seq;
        if (q->n != 5u) {
            continue; /* a vector exactly on an axis: fewer segments */
        }
        ++checked;
        for (i = 0u; i + 1u < q->n; ++i) {
            const uint8_t f = hil_fw_leg_transitions(q->states[i], q->states[i + 1u]);
            CHECK(f == 1u, "each change flips one leg: %u -> %u", q->states[i], q->states[i + 1u]);
            flips = (uint8_t)(flips + f);
        }
        CHECK(flips == 4u, "four transitions per period, got %u", flips);
        CHECK(q->states[0] == q->states[4] && q->states[1] == q->states[3], "symmetric");
        CHECK(q->states[0] == 0u || q->states[0] == 7u, "zero vector at the ends");
        CHECK(q->durations_ns[1] + q->durations_ns[3] >= q->durations_ns[2], "longer active vector outside");
        CHECK(hil_fw_leg_transitions(q->states[0], q->states[1]) == 1u, "zero adjacent to the longer vector");
        CHECK(q->durations_ns[0] + q->durations_ns[4] <= TS_NS, "zero time within Ts");
        CHECK(q->durations_ns[0] <= q->durations_ns[4] && q->durations_ns[4] - q->durations_ns[0] <= 1u,
              "zero halves equal");
    }
    CHECK(checked > 250, "most random cases give five segments (%d)", checked);
}

/* A problem with dq = alpha/beta (rotor at 0) and the deadbeat voltage of the given duties. */
static hil_fw_hv_problem_t problem_for(uint8_t sector, float d1, float d2, float th, hil_fw_hv_pair_t *pair)
{
    hil_fw_hv_problem_t p = {0};
    float a1;
    float b1;
    float a2;
    float b2;
    p.cos_m = cosf(th);
    p.sin_m = sinf(th);
    p.vdc = VDC;
    hil_fw_hv_table1(sector, &pair->v1, &pair->v2);
    hil_fw_state_voltage_ab(pair->v1, VDC, &a1, &b1);
    hil_fw_state_voltage_ab(pair->v2, VDC, &a2, &b2);
    p.v_alpha = d1 * a1 + d2 * a2;
    p.v_beta = d1 * b1 + d2 * b2;
    p.v_q = -p.v_alpha * p.sin_m + p.v_beta * p.cos_m;
    pair->d1 = d1;
    pair->d2 = d2;
    pair->err2 = 0.0f;
    return p;
}

static float code_q(uint8_t code, float th)
{
    float a;
    float b;
    hil_fw_state_voltage_ab(code, VDC, &a, &b);
    return -a * sinf(th) + b * cosf(th);
}

static void test_five_modes(void)
{
    const float thr = 8.0e-6f;
    hil_fw_hv_pair_t pair;
    hil_fw_hv_problem_t p;
    hil_fw_dwell_t d;
    uint8_t req;
    uint8_t mode;
    float dl;

    /* 1) all three >= T_THR: eq. (9) times unchanged. */
    p = problem_for(1u, 0.30f, 0.20f, 0.0f, &pair);
    mode = hil_fw_hv_modes(&p, &pair, thr, TS_NS, &d, &req);
    CHECK(mode == 1u && req == 1u, "mode 1, got %u", mode);
    CHECK(d.v_long == 4u && d.v_short == 6u, "u_opt1 = u1 (longer)");
    CHECK(d.t_long_ns == 30000u && d.t_short_ns == 20000u && d.t_zero_ns == 50000u, "mode 1 times");
    /* Fig. 4(b): u2 longer in S1. */
    p = problem_for(1u, 0.20f, 0.30f, 0.0f, &pair);
    mode = hil_fw_hv_modes(&p, &pair, thr, TS_NS, &d, &req);
    CHECK(mode == 1u && d.v_long == 6u && d.t_long_ns == 30000u, "mode 1 with u2 longer");

    /* 2) shorter active < T_THR: u_opt1 + zero, eq. (10) keeps psi_sq deadbeat (sector 2: both
     * vectors have q components, so the correction is visible). */
    p = problem_for(2u, 0.40f, 0.05f, -0.3f, &pair);
    mode = hil_fw_hv_modes(&p, &pair, thr, TS_NS, &d, &req);
    CHECK(mode == 2u && req == 2u, "mode 2, got %u", mode);
    CHECK(d.t_short_ns == 0u && d.t_long_ns + d.t_zero_ns == TS_NS, "mode 2: no shorter vector");
    dl = (float)d.t_long_ns / (float)TS_NS;
    CHECK_NEAR(dl * code_q(d.v_long, -0.3f), p.v_q, 0.01f, "eq. (10): d1 u1q = v_q");
    CHECK(d.t_long_ns != 40000u, "eq. (10) changed the time");

    /* 3) zero < T_THR: the pair alone, eq. (11). */
    p = problem_for(2u, 0.58f, 0.38f, -0.3f, &pair);
    mode = hil_fw_hv_modes(&p, &pair, thr, TS_NS, &d, &req);
    CHECK(mode == 3u && req == 3u, "mode 3, got %u", mode);
    CHECK(d.t_zero_ns == 0u && d.t_long_ns + d.t_short_ns == TS_NS, "mode 3: no zero vector");
    dl = (float)d.t_long_ns / (float)TS_NS;
    CHECK_NEAR(dl * code_q(d.v_long, -0.3f) + (1.0f - dl) * code_q(d.v_short, -0.3f), p.v_q, 0.01f, "eq. (11) psi_sq deadbeat");

    /* 4) shorter and zero < T_THR: u_opt1 for the whole period. */
    p = problem_for(3u, 0.90f, 0.05f, 0.0f, &pair);
    mode = hil_fw_hv_modes(&p, &pair, thr, TS_NS, &d, &req);
    CHECK(mode == 4u && req == 4u, "mode 4, got %u", mode);
    CHECK(d.t_long_ns == TS_NS && d.v_long == pair.v1, "mode 4: u_opt1 for Ts");

    /* 5) both active < T_THR: zero for the whole period. */
    p = problem_for(5u, 0.05f, 0.03f, 0.0f, &pair);
    mode = hil_fw_hv_modes(&p, &pair, thr, TS_NS, &d, &req);
    CHECK(mode == 5u && req == 5u, "mode 5, got %u", mode);
    CHECK(d.t_zero_ns == TS_NS, "mode 5: zero for Ts");

    /* Eq. (10) shortening u_opt1 below T_THR: dropped too (mode 5); T_THR = 0: always mode 1. */
    p = problem_for(1u, 0.12f, 0.07f, 0.0f, &pair); /* u1 has no q component at rotor angle 0 */
    p.v_q = 0.5f * 8.0e-6f / 100.0e-6f * code_q(6u, 0.0f);
    pair.v1 = 6u; /* longer vector with a q component */
    pair.v2 = 4u;
    mode = hil_fw_hv_modes(&p, &pair, 10.0e-6f, TS_NS, &d, &req);
    CHECK(req == 2u && mode == 5u, "eq. (10) result below T_THR -> zero (req %u mode %u)", req, mode);
    p = problem_for(4u, 0.001f, 0.0f, 0.0f, &pair);
    mode = hil_fw_hv_modes(&p, &pair, 0.0f, TS_NS, &d, &req);
    CHECK(mode == 1u, "T_THR = 0 keeps three vectors (zero-length ones dropped later)");
}

/* Full steps: modes 1, 4 and 5 from constructed measurements. */
static void test_modes_full_step(void)
{
    hil_fw_state_t s;
    hil_fw_cmd_t c;
    hil_fw_meas_t m;
    /* On the reference at standstill: only Rs*i is needed -> tiny active times -> zero (mode 5). */
    xiao_fixture(&s, HIL_FW_CTRL_HV_MPFC, 1.0f, 8.0e-6f);
    fw_set_applied(&s, 0u);
    m = fw_meas_dq(2u, 0.0f, 1.0f / (1.5f * 4.0f * 0.175f), 0.3f, 0.0f, VDC);
    hil_fw_step(&s, &m, 0u, &c);
    CHECK(s.ctrl.hv.mode == 5u && c.n_states == 1u && (c.states[0] == 0u || c.states[0] == 7u),
          "on reference at standstill: mode 5, got %u", s.ctrl.hv.mode);
    CHECK(c.vector_id / 16u == 5u, "vector_id carries the mode");
    /* Large torque step at speed: over-modulation -> one active vector (mode 4). */
    xiao_fixture(&s, HIL_FW_CTRL_HV_MPFC, 9.0f, 8.0e-6f);
    m = fw_meas_dq(3u, 0.0f, 0.0f, 1.0f, 1500.0f * HIL_FW_PI_F / 30.0f, VDC);
    hil_fw_step(&s, &m, 0u, &c);
    CHECK(s.ctrl.hv.mode == 4u && c.n_states == 1u && c.durations_ns[0] == TS_NS,
          "torque step: mode 4, got %u", s.ctrl.hv.mode);
    /* Steady state at 1000 rpm, 4 N*m, rotor angle in the middle of a sector: mode 1. */
    xiao_fixture(&s, HIL_FW_CTRL_HV_MPFC, 4.0f, 8.0e-6f);
    m = fw_meas_dq(4u, 0.0f, 4.0f / (1.5f * 4.0f * 0.175f), 0.0f, 1000.0f * HIL_FW_PI_F / 30.0f, VDC);
    hil_fw_step(&s, &m, 0u, &c);
    CHECK(s.ctrl.hv.mode == 1u, "steady state mid-sector: mode 1, got %u", s.ctrl.hv.mode);
}

/* Random operating points with T_THR = 8 us: no state and no interior leg pulse shorter than T_THR. */
static void test_no_narrow_pulses(void)
{
    const uint32_t thr_ns = 8000u;
    int modes[6] = {0};
    int k;
    for (k = 0; k < 3000; ++k) {
        hil_fw_state_t s;
        hil_fw_cmd_t c;
        const float rpm = 2200.0f * urand();
        const float th = 6.2831853f * urand();
        const float iq = 3.81f + (urand() - 0.5f) * 3.0f;
        const float id = (urand() - 0.5f) * 2.0f;
        hil_fw_meas_t m = fw_meas_dq((uint16_t)k, id, iq, th, rpm * HIL_FW_PI_F / 30.0f, VDC);
        const hil_fw_vseq_t *q;
        uint8_t leg;
        uint8_t i;
        xiao_fixture(&s, HIL_FW_CTRL_HV_MPFC, 4.0f, 8.0e-6f);
        hil_fw_step(&s, &m, 0u, &c);
        q = &s.ctrl.hv.seq;
        ++modes[s.ctrl.hv.mode];
        CHECK(sum_ns(q->durations_ns, q->n) == TS_NS && cmd_sum(&c) == TS_NS,
              "sums to Ts");
        /* Each vector's total time (halves summed) >= T_THR. */
        for (i = 0u; i < q->nest; ++i) {
            const uint32_t t = q->durations_ns[i] + (i + 1u < q->nest ? q->durations_ns[q->n - 1u - i] : 0u);
            CHECK(t >= thr_ns, "mode %u: vector %u applied %u ns < T_THR", s.ctrl.hv.mode, q->states[i], t);
        }
        /* Interior leg pulses (not touching the period edges) >= T_THR. */
        for (leg = 0u; leg < 3u; ++leg) {
            const uint8_t bit = (uint8_t)(2u - leg);
            uint32_t run = 0u;
            uint8_t start = 0u;
            for (i = 0u; i < q->n; ++i) {
                if (i > 0u && ((q->states[i] ^ q->states[i - 1u]) >> bit & 1u)) {
                    if (start > 0u) {
                        CHECK(run >= thr_ns, "mode %u leg %u pulse %u ns", s.ctrl.hv.mode, leg, run);
                    }
                    run = 0u;
                    start = i;
                }
                run += q->durations_ns[i];
            }
        }
    }
    for (k = 1; k <= 5; ++k) {
        CHECK(modes[k] > 0, "random sweep reaches mode %d (%d times)", k, modes[k]);
    }
}

/* 3vmpc: six predictions, always three vectors, the chosen pair leaves no flux error when feasible. */
static void test_3vmpc(void)
{
    int k;
    for (k = 0; k < 50; ++k) {
        hil_fw_state_t s;
        hil_fw_hv_problem_t p;
        hil_fw_hv_pair_t pair;
        hil_fw_cmd_t c;
        hil_fw_meas_t m = fw_meas_dq((uint16_t)k, 0.0f, 3.8f, 6.2831853f * urand(), 1000.0f * HIL_FW_PI_F / 30.0f, VDC);
        xiao_fixture(&s, HIL_FW_CTRL_3VMPC, 4.0f, 20.0e-6f); /* t_thr ignored by 3vmpc */
        step_capture(&s, &m, &p, &c);
        CHECK(c.candidates == 6u, "3vmpc evaluates six pairs");
        CHECK(s.ctrl.hv.mode == 1u, "3vmpc always mode 1");
        hil_fw_hv_pair_duties(&p, s.ctrl.hv.sector, 100.0e-6f, &pair);
        CHECK(pair.err2 < 1.0e-12f, "feasible deadbeat: no flux error left (%g)", (double)pair.err2);
    }
}

static void test_zero_rules_and_packing(void)
{
    const hil_fw_dwell_t d = {4u, 6u, 30000u, 20000u, 50000u}; /* u1 longer, u2 shorter */
    hil_fw_vseq_t q;
    uint8_t st[5];
    uint32_t du[5];
    uint8_t n;
    uint8_t st2[5];
    uint32_t du2[5];
    uint8_t n2;
    /* Paper rule: 000 next to u1 (100). */
    hil_fw_vseq_plan(&q, &d, HIL_FW_ZERO_PAPER, 7u, 0u, 0u);
    CHECK(q.n == 5u && q.states[0] == 0u && q.states[1] == 4u && q.states[2] == 6u, "0-100-110-100-0");
    CHECK(q.durations_ns[0] == 25000u && q.durations_ns[1] == 15000u && q.durations_ns[2] == 20000u,
          "halves of zero and longer vector");
    CHECK(hil_fw_vseq_transitions(7u, q.states, q.n) == 7u, "after 111: 3 boundary + 4 inside");
    /* min_transitions after 111: 111 outside, the shorter u2 (110) next to it, u1 in the middle. */
    hil_fw_vseq_plan(&q, &d, HIL_FW_ZERO_MIN_TRANSITIONS, 7u, 0u, 0u);
    CHECK(q.states[0] == 7u && q.states[1] == 6u && q.states[2] == 4u, "7-110-100-110-7");
    CHECK(hil_fw_vseq_transitions(7u, q.states, q.n) == 4u, "no boundary transition");
    hil_fw_vseq_plan(&q, &d, HIL_FW_ZERO_MIN_TRANSITIONS, 0u, 0u, 0u);
    CHECK(q.states[0] == 0u && q.states[1] == 4u, "after 000 both rules agree");

    /* Unfolded packing needs 5 slots. */
    hil_fw_vseq_plan(&q, &d, HIL_FW_ZERO_PAPER, 0u, 0u, 0u);
    CHECK(hil_fw_vseq_pack(&q, 0u, 0u, 3u, st, du) == 0u, "5 segments do not fit 3 slots");
    n = hil_fw_vseq_pack(&q, 0u, 0u, 5u, st, du);
    CHECK(n == 5u && sum_ns(du, n) == TS_NS, "5 slots: whole sequence");
    /* Folded: even 0-100-110 (t0, tL, tS), odd 110-100-0; two periods = one symmetric 2Ts pattern. */
    n = hil_fw_vseq_pack(&q, 1u, 0u, 3u, st, du);
    n2 = hil_fw_vseq_pack(&q, 1u, 1u, 3u, st2, du2);
    CHECK(n == 3u && st[0] == 0u && st[1] == 4u && st[2] == 6u, "even fold order");
    CHECK(du[0] == 50000u && du[1] == 30000u && du[2] == 20000u, "even fold: whole times");
    CHECK(n2 == 3u && st2[0] == 6u && st2[1] == 4u && st2[2] == 0u && du2[0] == 20000u && du2[2] == 50000u,
          "odd fold reversed");
    CHECK(hil_fw_vseq_transitions(st[n - 1u], st2, n2) == 2u, "no transition between the halves");
    CHECK(hil_fw_vseq_transitions(0u, st, n) == 2u, "two transitions per folded period");
    /* Mode 2 sequence: zero adjacent to the vector, 2 transitions; mode 3: L S L. */
    {
        const hil_fw_dwell_t d2 = {6u, 4u, 40000u, 0u, 60000u};
        const hil_fw_dwell_t d3 = {6u, 4u, 60000u, 40000u, 0u};
        hil_fw_vseq_plan(&q, &d2, HIL_FW_ZERO_PAPER, 0u, 0u, 0u);
        CHECK(q.n == 3u && q.states[0] == 7u && q.states[1] == 6u, "mode 2: 111-110-111");
        CHECK(hil_fw_vseq_transitions(q.states[0], q.states, q.n) == 2u, "mode 2: two transitions");
        hil_fw_vseq_plan(&q, &d3, HIL_FW_ZERO_PAPER, 0u, 0u, 0u);
        CHECK(q.n == 3u && q.states[0] == 6u && q.states[1] == 4u && q.durations_ns[1] == 40000u, "mode 3: L-S-L");
    }
}

/* High time of one leg (0 = a) over the applied (mirror-expanded) sequence [ns]. */
static uint32_t leg_high_ns(const hil_fw_cmd_t *c, uint8_t leg)
{
    uint8_t st[HIL_FW_MAX_APPLIED];
    uint32_t du[HIL_FW_MAX_APPLIED];
    const uint8_t n = hil_fw_vseq_expand(c->states, c->durations_ns, c->n_states, c->mirror, st, du);
    uint32_t t = 0u;
    uint8_t i;
    for (i = 0u; i < n; ++i) {
        t += ((st[i] >> (2u - leg)) & 1u) ? du[i] : 0u;
    }
    return t;
}

/* Mirror packing and expansion, and the symmetric dead-time compensation against hand values. */
static void test_mirror_packing_and_dt_comp(void)
{
    const hil_fw_dwell_t d = {4u, 6u, 30001u, 20000u, 49999u}; /* odd halves */
    hil_fw_vseq_t q;
    uint8_t st[5];
    uint32_t du[5];
    uint8_t xs[5];
    uint32_t xd[5];
    uint8_t n;
    uint8_t nx;
    uint8_t i;
    const float i_pos_a[3] = {5.0f, -2.0f, -3.0f};
    hil_fw_vseq_plan(&q, &d, HIL_FW_ZERO_PAPER, 0u, 0u, 0u);
    CHECK(hil_fw_vseq_pack_mirror(&q, 2u, st, du) == 0u, "3 distinct states need 3 slots");
    n = hil_fw_vseq_pack_mirror(&q, 3u, st, du);
    CHECK(n == 3u && st[0] == 0u && st[1] == 4u && st[2] == 6u, "mirror slots 0-100-110");
    CHECK(du[0] == 24999u && du[1] == 15000u && du[2] == 20002u, "first halves, odd ns to the middle (%u %u %u)",
          du[0], du[1], du[2]);
    nx = hil_fw_vseq_expand(st, du, n, 1u, xs, xd);
    CHECK(nx == 5u && xs[3] == 4u && xs[4] == 0u && xd[3] == du[1] && xd[4] == du[0] && sum_ns(xd, nx) == TS_NS,
          "expanded 0-100-110-100-0 sums to Ts");
    CHECK(hil_fw_vseq_transitions(0u, xs, nx) == 4u, "four one-leg transitions in one period");
    CHECK(hil_fw_vseq_expand(st, du, 1u, 1u, xs, xd) == 1u, "one state: mirror is a no-op");
    /* i_a > 0: 000 -> 100 is leg a rising inward (inner pulse high): earlier by t_dead/2, so a's
     * high time grows by 2.5 us; i_b < 0: 100 -> 110 (b rising inward): later by 1.25 us. */
    set_durations(du, 25000u, 15000u, 20000u);
    CHECK(hil_fw_vseq_dt_comp_mirror(st, du, 3u, i_pos_a, 2500u) == 2u, "two edges moved");
    CHECK(du[0] == 23750u && du[1] == 17500u && du[2] == 17500u, "hand values (%u %u %u)", du[0], du[1], du[2]);
    CHECK(2u * (du[0] + du[1]) + du[2] == TS_NS, "mirrored sum kept");
    /* Clamp: the middle slot cannot become negative. */
    set_durations(du, 25000u, 24500u, 1000u);
    (void)hil_fw_vseq_dt_comp_mirror(st, du, 3u, i_pos_a, 2500u);
    CHECK(du[2] == 0u && 2u * (du[0] + du[1]) == TS_NS, "clamped at the middle (%u)", du[2]);
    /* A 111 outer zero: 111 -> 110 is leg c falling inward; i_c < 0 -> inner low pulse: edge earlier. */
    set_states(st, 7u, 6u, 4u);
    set_durations(du, 20000u, 10000u, 40000u);
    (void)hil_fw_vseq_dt_comp_mirror(st, du, 3u, i_pos_a, 2500u);
    CHECK(du[0] == 18750u, "falling inward, i < 0: earlier (%u)", du[0]);
    for (i = 0u; i < 3u; ++i) {
        CHECK(du[i] <= TS_NS, "no wrap");
    }
}

static void test_dead_time_compensation(void)
{
    /* 000 -> 100 (leg a rises) -> 110 (leg b rises) */
    uint8_t st[3] = {0u, 4u, 6u};
    uint32_t du[3] = {50000u, 30000u, 20000u};
    const float i_pos_a[3] = {5.0f, -2.0f, -3.0f};
    const float i_neg_a[3] = {-5.0f, 2.0f, 3.0f};
    uint8_t moved;
    /* i_a > 0: a's rising edge is delayed by the dead time -> commanded 2.5 us earlier; i_b < 0:
     * b's rising edge is not delayed -> unchanged. */
    moved = hil_fw_vseq_dt_comp(st, du, 3u, i_pos_a, 2500u);
    CHECK(moved == 1u && du[0] == 47500u && du[1] == 32500u && du[2] == 20000u, "rising edge, i > 0");
    /* Reverse order (falling edges): 110 -> 100 (b falls, i_b > 0: immediate), 100 -> 000 (a falls,
     * i_a < 0: delayed -> earlier). */
    set_states(st, 6u, 4u, 0u);
    set_durations(du, 20000u, 30000u, 50000u);
    moved = hil_fw_vseq_dt_comp(st, du, 3u, i_neg_a, 2500u);
    CHECK(moved == 1u && du[0] == 20000u && du[1] == 27500u && du[2] == 52500u, "falling edge, i < 0");
    CHECK(sum_ns(du, 3u) == TS_NS, "sum kept");
    /* Too short a segment: the edge moves only as far as the segment allows. */
    set_durations(du, 1000u, 49000u, 50000u);
    set_states(st, 0u, 4u, 6u);
    (void)hil_fw_vseq_dt_comp(st, du, 3u, i_pos_a, 2500u);
    CHECK(du[0] == 0u && du[1] == 50000u, "clamped at the period start");
    /* Through the controller: with dt_comp every moved edge pair changes a leg's high time by
     * sign(i) * t_dead (symmetric, mirrored command). */
    {
        hil_fw_state_t s;
        hil_fw_hv_problem_t p;
        hil_fw_cmd_t c0;
        hil_fw_cmd_t c1;
        hil_fw_meas_t m = fw_meas_dq(2u, 0.0f, 3.8f, 0.4f, 1000.0f * HIL_FW_PI_F / 30.0f, VDC);
        uint8_t i;
        uint8_t leg;
        uint8_t changed = 0u;
        xiao_fixture(&s, HIL_FW_CTRL_HV_MPFC, 4.0f, 0.0f);
        hil_fw_step(&s, &m, 0u, &c0);
        xiao_fixture(&s, HIL_FW_CTRL_HV_MPFC, 4.0f, 0.0f);
        (void)hil_fw_set_param(&s, HIL_FW_P_T_DEAD, 2.5e-6f);
        CHECK(hil_fw_set_param(&s, HIL_FW_P_DT_COMP, 1.0f) == 0, "dt_comp accepted");
        CHECK(hil_fw_set_param(&s, HIL_FW_P_DT_COMP, 0.5f) == HIL_FW_E_PARAM_VALUE, "dt_comp integer");
        CHECK(hil_fw_set_param(&s, HIL_FW_P_ZERO_SELECT, 2.0f) == HIL_FW_E_PARAM_VALUE, "zero_select 0/1");
        step_capture(&s, &m, &p, &c1);
        CHECK(c0.n_states == c1.n_states && c1.mirror == 1u && cmd_sum(&c1) == TS_NS, "same shape, mirrored");
        for (i = 0u; i < c1.n_states; ++i) {
            CHECK(c0.states[i] == c1.states[i], "same states");
        }
        for (leg = 0u; leg < 3u; ++leg) {
            const int32_t h0 = (int32_t)leg_high_ns(&c0, leg);
            const int32_t h1 = (int32_t)leg_high_ns(&c1, leg);
            if (h1 != h0) {
                ++changed;
                CHECK(h1 - h0 == (p.i_abc[leg] > 0.0f ? 2500 : -2500), "leg %u high time %d ns vs i %g", leg,
                      h1 - h0, (double)p.i_abc[leg]);
            }
        }
        CHECK(s.ctrl.hv.dt_moved >= 1u && changed == s.ctrl.hv.dt_moved, "moved edges %u, legs changed %u",
              s.ctrl.hv.dt_moved, changed);
    }
}

/* Consecutive steps on a fixed trajectory: every period sends the whole symmetric sequence with the
 * mirror flag; the paper rule's boundary transitions are counted against min_transitions. */
static void test_mirrored_stream(void)
{
    hil_fw_state_t s;
    uint8_t rule;
    uint32_t trans[2] = {0u, 0u};
    uint32_t inside[2] = {0u, 0u};
    for (rule = 0u; rule < 2u; ++rule) {
        uint8_t prev = 0u;
        int k;
        xiao_fixture(&s, HIL_FW_CTRL_HV_MPFC, 4.0f, 0.0f);
        (void)hil_fw_set_param(&s, HIL_FW_P_ZERO_SELECT, (float)rule);
        { /* start from the steady-state voltage (the currents below never respond: open loop) */
            const float we = 4.0f * 1000.0f * HIL_FW_PI_F / 30.0f;
            const float thm = -0.5f * we * 100.0e-6f;
            const float vd = -we * 0.0085f * 3.81f;
            const float vq = 1.2f * 3.81f + we * 0.175f;
            set_applied_voltage(&s, vd * cosf(thm) - vq * sinf(thm), vd * sinf(thm) + vq * cosf(thm));
            prev = s.applied.states[2];
        }
        for (k = 0; k < 600; ++k) {
            hil_fw_cmd_t c;
            uint8_t xs[HIL_FW_MAX_APPLIED];
            uint32_t xd[HIL_FW_MAX_APPLIED];
            uint8_t nx;
            uint8_t i;
            const float wm = 1000.0f * HIL_FW_PI_F / 30.0f;
            const float th = 4.0f * wm * 100.0e-6f * (float)k;
            hil_fw_meas_t m = fw_meas_dq((uint16_t)k, 0.0f, 3.81f, th, wm, VDC);
            hil_fw_step(&s, &m, 0u, &c);
            nx = hil_fw_vseq_expand(c.states, c.durations_ns, c.n_states, c.mirror, xs, xd);
            CHECK(sum_ns(xd, nx) == TS_NS, "sum Ts");
            CHECK(nx == s.ctrl.hv.seq.n && c.mirror == (c.n_states > 1u), "expanded = the planned sequence");
            for (i = 0u; i < nx; ++i) {
                CHECK(xs[i] == s.ctrl.hv.seq.states[i] && s.applied.states[i] == xs[i], "same states, recorded");
            }
            CHECK(s.applied.n_states == nx, "applied holds the expanded sequence");
            trans[rule] += hil_fw_vseq_transitions(prev, xs, nx);
            inside[rule] += hil_fw_vseq_transitions(xs[0], xs, nx);
            prev = xs[nx - 1u];
        }
    }
    CHECK(trans[1] <= trans[0], "min_transitions never switches more: %u vs %u", trans[1], trans[0]);
    CHECK(inside[0] > 3u * 600u, "mostly four transitions inside a period (%u)", inside[0]);
    printf("mirrored stream, 600 periods: transitions paper %u (inside %u), min_transitions %u (inside %u)\n",
           trans[0], inside[0], trans[1], inside[1]);
}

int main(void)
{
    test_sector_table();
    test_pair_follows_flux_error();
    test_deadbeat();
    test_symmetric_sequence();
    test_five_modes();
    test_modes_full_step();
    test_no_narrow_pulses();
    test_3vmpc();
    test_zero_rules_and_packing();
    test_mirror_packing_and_dt_comp();
    test_dead_time_compensation();
    test_mirrored_stream();
    return FW_REPORT("test_hv_mpfc");
}
