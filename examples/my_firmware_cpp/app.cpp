// The firmware API (hil_app.h) of the C++ template: global objects, constructed before the first call
// (static constructors: __libc_init_array on the MCU, the loader on the host), and the firmware's own
// parameter table (hil_app_params.h): `hil run --param bandwidth=2000`.
#include "foc.hpp"
#include "hil_app.h"
#include "hil_app_params.h"

#ifndef MY_FW_BANDWIDTH
#define MY_FW_BANDWIDTH 1500.0f  // default current-loop bandwidth [rad/s] (`hil fw build --define MY_FW_BANDWIDTH=...`)
#endif

HIL_APP_PARAMS({"bandwidth", "rad/s", 128u, {0u, 0u, 0u}, MY_FW_BANDWIDTH, 100.0f, 20000.0f});

namespace {

constexpr uint8_t kControllerExternal = 255u;

const fw::SineTable g_trig;        // built by its constructor
fw::FocController g_foc(g_trig);  // holds a reference to it

}  // namespace

void hil_app_init(void)
{
    g_foc.settings = fw::Settings();
    g_foc.settings.bandwidth = hil_app_params[0].def;
    g_foc.selected = false;
    g_foc.reset();
}

int hil_app_config(uint8_t param_id, float value)
{
    return g_foc.configure(param_id, value) ? HIL_APP_OK : HIL_APP_E_PARAM;
}

int hil_app_select(uint8_t controller_id)
{
    if (controller_id != kControllerExternal && controller_id != 0u) {
        return HIL_APP_E_NOT_IMPLEMENTED;
    }
    g_foc.selected = controller_id == kControllerExternal;
    return HIL_APP_OK;
}

void hil_app_reset(void)
{
    g_foc.reset();
}

int hil_app_setpoint(uint8_t enable, uint8_t mode, float reference)
{
    return g_foc.setpoint(enable, mode, reference) ? HIL_APP_OK : HIL_APP_E_SETPOINT;
}

void hil_app_step(const hil_app_meas_t *m, hil_app_cmd_t *cmd)
{
    g_foc.step(*m, *cmd);
}
