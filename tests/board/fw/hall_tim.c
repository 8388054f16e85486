/* Hall interface test: 170 MHz, TIM1 centre-aligned at 20 kHz (the carrier the run side paces), hall A/B/C on
 * TIM4 CH1-CH3 (PB6/PB7/PB8): CR2.TI1S (their XOR on TI1), reset mode on TI1F_ED, CC1 capturing TRC, 1 MHz counter
 * (PSC 169), URS (no update on the reset); the CC1 interrupt stores each capture: the time between hall edges [us]. */
#include "regs.h"
#define ARR_VALUE 4250u
#define TIM4 0x40000800u
#define KEEP 64u
volatile uint32_t captures_n;
volatile uint32_t captures[KEEP];

void TIM4_IRQHandler(void) {
  if (TIM_SR(TIM4) & (1u << 1)) {
    captures[captures_n % KEEP] = TIM_CCR1(TIM4);
    ++captures_n;
    TIM_SR(TIM4) = ~(1u << 1);
  }
}

int main(void) {
  SCB_CPACR |= 0xFu << 20;
  clock_170mhz();
  RCC_APB1ENR1 |= 1u << 2;                   /* TIM4EN */
  RCC_APB2ENR |= 1u << 11;                   /* TIM1EN */
  TIM_PSC(TIM4) = 169u;
  TIM_ARR(TIM4) = 0xFFFFu;
  TIM_CR2(TIM4) = 1u << 7;                   /* TI1S */
  TIM_CCMR1(TIM4) = 3u;                      /* CC1S = TRC */
  TIM_CCER(TIM4) = 1u;                       /* CC1E */
  TIM_SMCR(TIM4) = 4u | 4u << 4;             /* SMS reset mode, TS TI1F_ED */
  TIM_DIER(TIM4) = 1u << 1;                  /* CC1IE */
  TIM_EGR(TIM4) = 1u;
  TIM_SR(TIM4) = 0u;
  TIM_CR1(TIM4) = 1u | 1u << 2;              /* CEN, URS */
  NVIC_ISER0 = 1u << 30;                     /* TIM4 */
  TIM_ARR(TIM1) = ARR_VALUE;
  TIM_RCR(TIM1) = 1u;
  TIM_EGR(TIM1) = 1u;
  TIM_CR1(TIM1) = 1u | 1u << 5 | 1u << 7;    /* CEN, CMS = 1, ARPE */
  for (;;) { __asm volatile("wfi"); }
}
