/* Reference firmware: dual three-phase VSD, code voltages and vector tables (see hil_fw_six.h). */
#include "hil_fw_six.h"
#include "hil_fw_types.h"

#define H3 0.8660254037844386f

/* VSD rows without the 1/3 factor: alpha, beta, x, y over A B C U V W. */
static const float vsd[4][6] = {
    {1.0f, -0.5f, -0.5f, H3, -H3, 0.0f},
    {0.0f, H3, -H3, 0.5f, 0.5f, -1.0f},
    {1.0f, -0.5f, -0.5f, -H3, H3, 0.0f},
    {0.0f, -H3, H3, 0.5f, 0.5f, -1.0f},
};

const uint8_t hil_fw_six_g1[HIL_FW_SIX_SECTORS] = {36u, 52u, 54u, 22u, 18u, 26u, 27u, 11u, 9u, 41u, 45u, 37u};
const uint8_t hil_fw_six_g2[HIL_FW_SIX_SECTORS] = {53u, 38u, 20u, 50u, 30u, 19u, 10u, 25u, 43u, 13u, 33u, 44u};

static float row_dot(int r, const float *v6)
{
    float acc = 0.0f;
    int k;
    for (k = 0; k < 6; ++k) {
        acc += vsd[r][k] * v6[k];
    }
    return acc * (1.0f / 3.0f);
}

void hil_fw_vsd(const float *i6, float *alpha, float *beta, float *x, float *y)
{
    *alpha = row_dot(0, i6);
    *beta = row_dot(1, i6);
    *x = row_dot(2, i6);
    *y = row_dot(3, i6);
}

void hil_fw_six_code_voltage(uint8_t code, float vdc, float *v4)
{
    float legs[6];
    int k;
    for (k = 0; k < 6; ++k) {
        legs[k] = (float)((code >> (5 - k)) & 1u) * vdc; /* per-set common mode drops out of each row */
    }
    for (k = 0; k < 4; ++k) {
        v4[k] = row_dot(k, legs);
    }
}

void hil_fw_six_mean_voltage_ab(const uint8_t *states, const uint32_t *durations_ns, uint8_t n_states,
                                float vdc, float *u_alpha, float *u_beta)
{
    float ua = 0.0f;
    float ub = 0.0f;
    float total = 0.0f;
    uint8_t i;
    for (i = 0u; i < n_states && i < HIL_FW_MAX_APPLIED; ++i) {
        float v[4];
        const float w = (float)durations_ns[i];
        hil_fw_six_code_voltage(states[i], vdc, v);
        ua += w * v[0];
        ub += w * v[1];
        total += w;
    }
    *u_alpha = total > 0.0f ? ua / total : 0.0f;
    *u_beta = total > 0.0f ? ub / total : 0.0f;
}

uint8_t hil_fw_six_zero_for(uint8_t prev_code)
{
    uint8_t ones = 0u;
    int k;
    for (k = 0; k < 6; ++k) {
        ones = (uint8_t)(ones + ((prev_code >> k) & 1u));
    }
    return ones <= 3u ? 0u : 63u;
}
