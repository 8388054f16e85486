/* Reference firmware: two-level inverter voltage vectors, eq. (3). */
#include "hil_fw_inverter.h"
#include "hil_fw_transforms.h"

const uint8_t hil_fw_vector_state[8] = {0u, 4u, 6u, 2u, 3u, 1u, 5u, 7u};
const uint8_t hil_fw_state_vector[8] = {0u, 5u, 3u, 4u, 1u, 6u, 2u, 7u};

void hil_fw_state_voltage_ab(uint8_t code, float vdc, float *u_alpha, float *u_beta)
{
    const float sa = (float)((code >> 2) & 1u);
    const float sb = (float)((code >> 1) & 1u);
    const float sc = (float)(code & 1u);
    *u_alpha = (2.0f / 3.0f) * vdc * (sa - 0.5f * (sb + sc));
    *u_beta = (1.0f / HIL_FW_SQRT3_F) * vdc * (sb - sc);
}

void hil_fw_cmd_mean_voltage_ab(const uint8_t *states, const uint32_t *durations_ns, uint8_t n_states,
                                float vdc, float *u_alpha, float *u_beta)
{
    float ua = 0.0f;
    float ub = 0.0f;
    float total = 0.0f;
    uint8_t i;
    for (i = 0u; i < n_states && i < HIL_FW_MAX_SUBSTATES; ++i) {
        float a;
        float b;
        const float w = (float)durations_ns[i];
        hil_fw_state_voltage_ab(states[i], vdc, &a, &b);
        ua += w * a;
        ub += w * b;
        total += w;
    }
    if (total > 0.0f) {
        *u_alpha = ua / total;
        *u_beta = ub / total;
    } else {
        *u_alpha = 0.0f;
        *u_beta = 0.0f;
    }
}

uint8_t hil_fw_leg_transitions(uint8_t a, uint8_t b)
{
    const uint8_t x = (uint8_t)((a ^ b) & 7u);
    return (uint8_t)((x & 1u) + ((x >> 1) & 1u) + ((x >> 2) & 1u));
}

uint8_t hil_fw_zero_state_for(uint8_t prev_code)
{
    return hil_fw_leg_transitions(prev_code, 0u) <= 1u ? 0u : 7u;
}
