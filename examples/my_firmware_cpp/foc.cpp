// The C++ template's control law (foc.hpp).
#include "foc.hpp"

#include "hil_ids.h"

namespace fw {

namespace {

float clamp(float x, float lim) { return x > lim ? lim : (x < -lim ? -lim : x); }

bool finite(float x) { return x == x && x - x == 0.0f; }  // not NaN, not infinite (no libm)

// sin on [-pi, pi] by its Taylor series to x^15 folded to [-pi/2, pi/2] (error < 1e-7): fills the table once
float series_sin(float x)
{
    const float half_pi = 0.25f * kTwoPi;
    if (x > half_pi) {
        x = 0.5f * kTwoPi - x;
    } else if (x < -half_pi) {
        x = -0.5f * kTwoPi - x;
    }
    const float x2 = x * x;
    float term = x;
    float sum = x;
    for (int k = 1; k <= 7; ++k) {
        term *= -x2 / static_cast<float>((2 * k) * (2 * k + 1));
        sum += term;
    }
    return sum;
}

}  // namespace

SineTable::SineTable()
{
    for (int i = 0; i <= kSize; ++i) {
        table_[i] = series_sin(static_cast<float>(i) * (kTwoPi / kSize) - 0.5f * kTwoPi);
    }
}

float SineTable::sin(float x) const
{
    // position in the table: (x + pi) / 2pi turns, wrapped into [0, 1)
    float turns = (x + 0.5f * kTwoPi) * (1.0f / kTwoPi);
    turns -= static_cast<float>(static_cast<int32_t>(turns));
    if (turns < 0.0f) {
        turns += 1.0f;
    }
    const float pos = turns * kSize;
    int i = static_cast<int>(pos);
    if (i >= kSize) {
        i = kSize - 1;
    }
    const float frac = pos - static_cast<float>(i);
    return table_[i] + frac * (table_[i + 1] - table_[i]);
}

float PiController::step(float e, float kp, float ki, float dt, float limit)
{
    const float next = integ_ + ki * e * dt;
    const float out = kp * e + next;
    if (out > limit || out < -limit) {
        if ((out > limit && e < 0.0f) || (out < -limit && e > 0.0f)) {
            integ_ = next;  // integrate only while it does not push further into the limit
        }
        return clamp(out, limit);
    }
    integ_ = next;
    return out;
}

void SpaceVectorModulator::modulate(float v_alpha, float v_beta, float vdc, uint32_t ts_ns,
                                    hil_app_cmd_t *cmd) const
{
    // phase voltages (amplitude-invariant inverse Clarke), legs a, b, c = bits 4, 2, 1 of a switching code
    const float v[3] = {v_alpha, -0.5f * v_alpha + 0.5f * kSqrt3 * v_beta, -0.5f * v_alpha - 0.5f * kSqrt3 * v_beta};
    static const uint8_t bit[3] = {4u, 2u, 1u};
    int hi = 0;
    int lo = 0;
    for (int k = 1; k < 3; ++k) {
        hi = v[k] > v[hi] ? k : hi;
        lo = v[k] < v[lo] ? k : lo;
    }
    if (hi == lo) {  // zero reference
        lo = (hi + 1) % 3;
    }
    const int mid = 3 - hi - lo;
    float ta = (v[hi] - v[mid]) / vdc;  // time fraction of the vector with the highest leg alone
    float tb = (v[mid] - v[lo]) / vdc;  // ... with the highest two legs
    if (ta + tb > 1.0f) {               // beyond the hexagon: keep the direction
        const float s = 1.0f / (ta + tb);
        ta *= s;
        tb *= s;
    }
    uint32_t d0 = static_cast<uint32_t>((1.0f - ta - tb) * 0.5f * static_cast<float>(ts_ns));
    uint32_t d1 = static_cast<uint32_t>(ta * 0.5f * static_cast<float>(ts_ns));
    if (2u * (d0 + d1) > ts_ns) {
        d1 = ts_ns / 2u - d0;
    }
    cmd->n_states = 3u;
    cmd->states[0] = 0u;
    cmd->states[1] = bit[hi];
    cmd->states[2] = static_cast<uint8_t>(bit[hi] | bit[mid]);
    cmd->durations_ns[0] = d0;
    cmd->durations_ns[1] = d1;
    cmd->durations_ns[2] = ts_ns - 2u * (d0 + d1);
    cmd->mirror = 1u;
}

bool FocController::configure(uint8_t id, float value)
{
    if (!finite(value)) {
        return false;
    }
    const bool positive = value > 0.0f;
    Settings &s = settings;
    switch (id) {
    case HIL_FW_P_RS: s.rs = value; return true;
    case HIL_FW_P_LD: s.ld = value; return positive;
    case HIL_FW_P_LQ: s.lq = value; return positive;
    case HIL_FW_P_PSI_F: s.psi_f = value; return positive;
    case HIL_FW_P_POLE_PAIRS: s.pole_pairs = value; return positive;
    case HIL_FW_P_TS: s.ts = value; return positive;
    case HIL_FW_P_VDC: s.vdc = value; return positive;
    case HIL_FW_P_SPEED_KP: s.speed_kp = value; return true;
    case HIL_FW_P_SPEED_KI: s.speed_ki = value; return true;
    case HIL_FW_P_TORQUE_LIMIT: s.torque_limit = value; return true;
    case HIL_FW_P_TORQUE_INTEGRATOR_INIT: s.torque_init = value; return true;
    case HIL_FW_P_CURRENT_LIMIT: s.current_limit = value; return true;
    case 128u: s.bandwidth = value; return true;  // "bandwidth" (app.cpp's parameter table)
    default: return true;                          // not used by this firmware: acknowledged
    }
}

void FocController::reset()
{
    speed_.reset(settings.torque_init);
    id_loop_.reset(0.0f);
    iq_loop_.reset(0.0f);
}

bool FocController::setpoint(uint8_t enable, uint8_t mode, float reference)
{
    (void)enable;
    if (mode > 1u || !finite(reference)) {
        return false;
    }
    mode_ = mode;
    reference_ = reference;
    return true;
}

void FocController::step(const hil_app_meas_t &m, hil_app_cmd_t &cmd)
{
    const Settings &s = settings;
    const uint32_t ts_ns = static_cast<uint32_t>(s.ts * 1.0e9f + 0.5f);
    const float vdc = m.vdc > 0.0f ? m.vdc : s.vdc;
    const float vlim = vdc / kSqrt3;
    if (m.n_phases != 3u || !selected) {
        cmd.n_states = 1u;
        cmd.states[0] = 0u;
        cmd.durations_ns[0] = ts_ns;
        cmd.status = m.n_phases != 3u ? 5u : 0u;
        return;
    }
    const float torque = mode_ == 0u
        ? speed_.step(reference_ - m.omega_m, s.speed_kp, s.speed_ki, s.ts, s.torque_limit)
        : clamp(reference_, s.torque_limit);
    const float iq_ref = clamp(torque / (1.5f * s.pole_pairs * s.psi_f), s.current_limit);
    // Clarke (amplitude invariant) and Park
    const float i_alpha = (2.0f * m.i[0] - m.i[1] - m.i[2]) / 3.0f;
    const float i_beta = (m.i[1] - m.i[2]) / kSqrt3;
    float c = trig_.cos(m.theta_e);
    float sn = trig_.sin(m.theta_e);
    const float id = i_alpha * c + i_beta * sn;
    const float iq = -i_alpha * sn + i_beta * c;
    // current loops (bandwidth-tuned) with decoupling feed-forward
    const float we = s.pole_pairs * m.omega_m;
    const float vd = id_loop_.step(0.0f - id, s.bandwidth * s.ld, s.bandwidth * s.rs, s.ts, vlim) - we * s.lq * iq;
    const float vq = iq_loop_.step(iq_ref - iq, s.bandwidth * s.lq, s.bandwidth * s.rs, s.ts, vlim)
                     + we * (s.ld * id + s.psi_f);
    // the command is applied one period later, for one period: rotate to the middle of that period
    const float th = m.theta_e + 1.5f * we * s.ts;
    c = trig_.cos(th);
    sn = trig_.sin(th);
    svm_.modulate(vd * c - vq * sn, vd * sn + vq * c, vdc, ts_ns, &cmd);
    cmd.torque_ref = torque;
    cmd.iq_ref = iq_ref;
    cmd.id_ref = 0.0f;
}

}  // namespace fw
