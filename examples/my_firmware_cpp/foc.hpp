// The C++ template firmware's control law: field-oriented control of a three-phase PMSM in a few small classes
// (a sine table built by its constructor, PI controllers, a space-vector modulator, the FOC itself). No heap, no
// exceptions, no RTTI, no libm: its own sine table keeps SIL (x86-64) and QEMU (Cortex-M4F) bit-identical.
#ifndef MY_FIRMWARE_CPP_FOC_HPP
#define MY_FIRMWARE_CPP_FOC_HPP

#include <stdint.h>

#include "hil_app.h"

namespace fw {

constexpr float kTwoPi = 6.28318531f;
constexpr float kSqrt3 = 1.73205081f;

// sin/cos by linear interpolation in a 1024-entry table filled at start-up (a static constructor: on the MCU
// it runs from __libc_init_array; if it did not, every angle would read 0 and the motor would not turn).
class SineTable {
public:
    static constexpr int kSize = 1024;
    SineTable();
    float sin(float x) const;
    float cos(float x) const { return sin(x + 0.25f * kTwoPi); }

private:
    float table_[kSize + 1];
};

// Parallel PI, forward rectangle, clamping anti-windup: out = kp*e + integ, |out| <= limit.
class PiController {
public:
    void reset(float integ) { integ_ = integ; }
    float step(float e, float kp, float ki, float dt, float limit);

private:
    float integ_ = 0.0f;
};

// Five-segment space-vector modulation as one mirrored Command: V0 - Va - Vb - Va - V0 with Va the vector of
// the highest leg alone, Vb the highest two legs (phase voltages sorted, no angle function needed).
class SpaceVectorModulator {
public:
    void modulate(float v_alpha, float v_beta, float vdc, uint32_t ts_ns, hil_app_cmd_t *cmd) const;
};

// The firmware's parameters (ConfigParam ids of hil_ids.h, SI units) and its own current-loop bandwidth.
struct Settings {
    float rs = 1.0f, ld = 0.01f, lq = 0.01f, psi_f = 0.1f, pole_pairs = 1.0f, ts = 1.0e-4f, vdc = 300.0f;
    float speed_kp = 0.0f, speed_ki = 0.0f, torque_limit = 10.0f, torque_init = 0.0f, current_limit = 10.0f;
    float bandwidth = 1500.0f;  // current-loop bandwidth [rad/s]: firmware parameter "bandwidth" (id 128)
};

class FocController {
public:
    explicit FocController(const SineTable &trig) : trig_(trig) {}
    Settings settings;
    bool configure(uint8_t param_id, float value);
    void reset();
    bool setpoint(uint8_t enable, uint8_t mode, float reference);
    void step(const hil_app_meas_t &m, hil_app_cmd_t &cmd);
    bool selected = false;

private:
    const SineTable &trig_;
    SpaceVectorModulator svm_;
    PiController speed_, id_loop_, iq_loop_;
    uint8_t mode_ = 0u;
    float reference_ = 0.0f;
};

}  // namespace fw

#endif
