/* Reference firmware: amplitude-invariant Clarke/Park transforms. */
#include <math.h>

#include "hil_fw_transforms.h"

void hil_fw_clarke(float a, float b, float c, float *alpha, float *beta)
{
    *alpha = (2.0f * a - b - c) * (1.0f / 3.0f);
    *beta = (b - c) * (1.0f / HIL_FW_SQRT3_F);
}

void hil_fw_clarke_inv(float alpha, float beta, float *a, float *b, float *c)
{
    const float h = 0.5f * HIL_FW_SQRT3_F * beta;
    *a = alpha;
    *b = -0.5f * alpha + h;
    *c = -0.5f * alpha - h;
}

void hil_fw_park(float alpha, float beta, float cos_th, float sin_th, float *d, float *q)
{
    *d = alpha * cos_th + beta * sin_th;
    *q = -alpha * sin_th + beta * cos_th;
}

void hil_fw_park_inv(float d, float q, float cos_th, float sin_th, float *alpha, float *beta)
{
    *alpha = d * cos_th - q * sin_th;
    *beta = d * sin_th + q * cos_th;
}

void hil_fw_mid_angles(float cos_th, float sin_th, float wts, float *c1, float *s1, float *c2, float *s2)
{
    const float ch = cosf(0.5f * wts);
    const float sh = sinf(0.5f * wts);
    const float cw = 1.0f - 2.0f * sh * sh; /* cos/sin of wts */
    const float sw = 2.0f * sh * ch;
    *c1 = cos_th * ch - sin_th * sh;
    *s1 = sin_th * ch + cos_th * sh;
    *c2 = *c1 * cw - *s1 * sw;
    *s2 = *s1 * cw + *c1 * sw;
}
