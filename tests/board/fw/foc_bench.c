/* A field-oriented current loop as a drive firmware has it, for the board's benchmark: 170 MHz, TIM1
 * centre-aligned 20 kHz with dead time and preload, ADC1/ADC2 injected phase currents triggered by OC4REF
 * (TRGO2) near the peak, the loop in the ADC ISR (Clarke, Park from the TIM3 encoder angle, two PI, inverse
 * Park, min/max-injection SVPWM into CCR1-3), a 1 kHz speed PI on SysTick. Float32 on the FPU. */
#include "regs.h"
#define ARR_VALUE 4250u
#define LINES 1024u
#define POLE_PAIRS 4.0f
#define TWO_PI 6.2831853f
volatile float id_ref, iq_ref, speed_ref = 50.0f, speed_meas, vd, vq;
static float id_i, iq_i, spd_i, theta_last;
static uint32_t enc_last;
volatile uint32_t isr_count;

static float sin_poly(float x) {            /* x in [-pi, pi] */
  float x2 = x * x;
  return x * (1.0f - x2 * (0.16666667f - x2 * (0.0083333333f - x2 * 0.00019841270f)));
}
static float wrap(float x) { while (x > 3.1415927f) { x -= TWO_PI; } while (x < -3.1415927f) { x += TWO_PI; } return x; }
static float clampf(float x, float lo, float hi) { return x < lo ? lo : x > hi ? hi : x; }

void ADC1_2_IRQHandler(void) {
  ADC_ISR(ADC1) = 1u << 6 | 1u << 5;
  ADC_ISR(ADC2) = 1u << 6 | 1u << 5;
  const float k = 3.3f / 4095.0f / 0.01f;   /* A per code, 10 mV/A around 1.65 V */
  float ia = ((float)ADC_JDR1(ADC1) - 2047.5f) * k;
  float ib = ((float)ADC_JDR1(ADC2) - 2047.5f) * k;
  uint32_t cnt = TIM_CNT(TIM3);
  float theta_m = (float)cnt * (TWO_PI / (4.0f * (float)LINES));
  float th = wrap(theta_m * POLE_PAIRS);
  float s = sin_poly(th), c = sin_poly(wrap(th + 1.5707963f));
  float alpha = ia, beta = (ia + 2.0f * ib) * 0.57735027f;
  float id = c * alpha + s * beta, iq = -s * alpha + c * beta;
  float ed = id_ref - id, eq = iq_ref - iq;
  id_i = clampf(id_i + 0.05f * ed, -20.0f, 20.0f);
  iq_i = clampf(iq_i + 0.05f * eq, -20.0f, 20.0f);
  vd = clampf(0.5f * ed + id_i, -27.0f, 27.0f);
  vq = clampf(0.5f * eq + iq_i, -27.0f, 27.0f);
  float va = c * vd - s * vq, vb = s * vd + c * vq;
  float ua = va, ub = -0.5f * va + 0.8660254f * vb, uc = -0.5f * va - 0.8660254f * vb;
  float mx = ua > ub ? (ua > uc ? ua : uc) : (ub > uc ? ub : uc);
  float mn = ua < ub ? (ua < uc ? ua : uc) : (ub < uc ? ub : uc);
  float off = -0.5f * (mx + mn), inv = 1.0f / 48.0f;
  TIM_CCR1(TIM1) = (uint32_t)(clampf(0.5f + (ua + off) * inv, 0.0f, 1.0f) * (float)ARR_VALUE);
  TIM_CCR2(TIM1) = (uint32_t)(clampf(0.5f + (ub + off) * inv, 0.0f, 1.0f) * (float)ARR_VALUE);
  TIM_CCR3(TIM1) = (uint32_t)(clampf(0.5f + (uc + off) * inv, 0.0f, 1.0f) * (float)ARR_VALUE);
  theta_last = theta_m;
  ++isr_count;
}

void SysTick_Handler(void) {                /* 1 kHz speed loop */
  uint32_t cnt = TIM_CNT(TIM3);
  int32_t d = (int32_t)(cnt - enc_last);
  if (d > (int32_t)(2u * LINES)) { d -= (int32_t)(4u * LINES); }
  if (d < -(int32_t)(2u * LINES)) { d += (int32_t)(4u * LINES); }
  enc_last = cnt;
  speed_meas = (float)d * (TWO_PI / (4.0f * (float)LINES)) * 1000.0f;
  float e = speed_ref - speed_meas;
  spd_i = clampf(spd_i + 0.002f * e, -10.0f, 10.0f);
  iq_ref = clampf(0.2f * e + spd_i, -10.0f, 10.0f);
}

static void adc_on(uint32_t adc, uint32_t jsqr) {
  ADC_CR(adc) = 1u << 28;
  for (volatile int i = 0; i < 4000; ++i) { }
  ADC_CR(adc) |= 1u << 31;
  while (ADC_CR(adc) & (1u << 31)) { }
  ADC_CR(adc) |= 1u;
  while (!(ADC_ISR(adc) & 1u)) { }
  ADC_SMPR1(adc) = 2u << 3 | 2u << 6;
  ADC_JSQR(adc) = jsqr;
}

int main(void) {
  SCB_CPACR |= 0xFu << 20;
  clock_170mhz();
  RCC_AHB2ENR |= 1u << 13;
  RCC_APB2ENR |= 1u << 11;
  RCC_APB1ENR1 |= 1u << 1;
  TIM_SMCR(TIM3) = 3u;
  TIM_ARR(TIM3) = 4u * LINES - 1u;
  TIM_CR1(TIM3) = 1u;
  ADC12_CCR = 3u << 16;
  adc_on(ADC1, 0u | 8u << 2 | 1u << 7 | 1u << 9);   /* IN1 (i_a) on TRGO2 rising */
  adc_on(ADC2, 0u | 8u << 2 | 1u << 7 | 1u << 9);   /* IN1 (i_b) */
  ADC_IER(ADC1) = 1u << 6;
  ADC_CR(ADC1) |= 1u << 3;
  ADC_CR(ADC2) |= 1u << 3;
  NVIC_IPR(18) = 0x10;
  NVIC_ISER0 = 1u << 18;
  SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | 0x40u << 24;   /* SysTick below the current loop */
  SYST_RVR = 170000u - 1u;
  SYST_CVR = 0;
  SYST_CSR = 7u;
  TIM_ARR(TIM1) = ARR_VALUE;
  TIM_RCR(TIM1) = 1u;
  TIM_CCMR1(TIM1) = (6u << 4 | 1u << 3) | (6u << 12 | 1u << 11);
  TIM_CCMR2(TIM1) = (6u << 4 | 1u << 3) | (7u << 12 | 1u << 11);
  TIM_CCR1(TIM1) = ARR_VALUE / 2u; TIM_CCR2(TIM1) = ARR_VALUE / 2u; TIM_CCR3(TIM1) = ARR_VALUE / 2u;
  TIM_CCR4(TIM1) = ARR_VALUE - 10u;
  TIM_CCER(TIM1) = 0x1555u;
  TIM_BDTR(TIM1) = 1u << 15 | 85u;           /* MOE, 500 ns */
  TIM_CR2(TIM1) = 7u << 20;
  TIM_EGR(TIM1) = 1u;
  TIM_CR1(TIM1) = 1u | 1u << 5 | 1u << 7;
  for (;;) { __asm volatile("wfi"); }
}
