/* TIM1 + ADC test: 170 MHz, TIM1 centre-aligned at 20 kHz (ARR 4250), update at the valley (RCR 1), CCR1-3
 * preloaded PWM mode 1, OC4REF (PWM mode 2, CCR4 = 4240) as TRGO2 triggering ADC1's injected pair (IN1, IN2) on
 * its rising edge near the carrier peak; the JEOS interrupt stores the results and writes CCR1 = its own count
 * (LATE: after a delay longer than the rest of the period; FAULT_AT: reads nothing in that period; UNMODELLED_AT:
 * writes COMP1_CSR in that period; BREAK: the break input enabled, active low, its interrupt counting the breaks and
 * clearing BIF). TIM3 in encoder mode x4. */
#include "regs.h"
#define ARR_VALUE 4250u
volatile uint32_t isr_count, jdr1, jdr2, cnt_at_entry, enc_count, enc_dir, sink, break_count, break_sr;

#ifdef BREAK
void TIM1_BRK_TIM15_IRQHandler(void) {
  break_sr = TIM_SR(TIM1);
  ++break_count;
  TIM_SR(TIM1) = ~(1u << 7);                  /* clear BIF (it stays set while the break input is active) */
  TIM_DIER(TIM1) &= ~(1u << 7);               /* one interrupt per trip: the ISR would re-enter while BRK is held */
}
#endif

void ADC1_2_IRQHandler(void) {
  cnt_at_entry = TIM_CNT(TIM1);
  ADC_ISR(ADC1) = 1u << 6 | 1u << 5;          /* clear JEOS, JEOC */
  jdr1 = ADC_JDR1(ADC1);
  jdr2 = ADC_JDR2(ADC1);
  ++isr_count;
#ifdef FAULT_AT
  if (isr_count == FAULT_AT) { sink = REG(0x9F000000u); } /* a precise BusFault inside the current loop */
#endif
#ifdef UNMODELLED_AT
  if (isr_count == UNMODELLED_AT) { REG(0x40010200u) = 1u; } /* COMP1_CSR, which the board does not model */
#endif
#ifdef LATE
  for (volatile uint32_t i = 0; i < 1000u; ++i) { }
#endif
  TIM_CCR1(TIM1) = isr_count;
  TIM_CCR2(TIM1) = 1000u;
  TIM_CCR3(TIM1) = 3000u;
  enc_count = TIM_CNT(TIM3);
  enc_dir = TIM_CR1(TIM3) >> 4 & 1u;
}

int main(void) {
  SCB_CPACR |= 0xFu << 20;
  clock_170mhz();
  RCC_AHB2ENR |= 1u << 13;                    /* ADC12EN */
  RCC_APB2ENR |= 1u << 11;                    /* TIM1EN */
  RCC_APB1ENR1 |= 1u << 1;                    /* TIM3EN */
  /* TIM3: encoder mode 3 (x4), ARR = 4 * 1024 - 1 */
  TIM_SMCR(TIM3) = 3u;
  TIM_ARR(TIM3) = 4u * 1024u - 1u;
  TIM_CR1(TIM3) = 1u;
  /* ADC1: regulator, calibration, enable, injected IN1, IN2 on TIM1_TRGO2 rising */
  ADC12_CCR = 3u << 16;                       /* HCLK/4 */
  ADC_CR(ADC1) = 1u << 28;                    /* DEEPPWD off, ADVREGEN */
  for (volatile int i = 0; i < 4000; ++i) { }
  ADC_CR(ADC1) |= 1u << 31;                   /* ADCAL */
  while (ADC_CR(ADC1) & (1u << 31)) { }
  ADC_CR(ADC1) |= 1u;                         /* ADEN */
  while (!(ADC_ISR(ADC1) & 1u)) { }           /* ADRDY */
  ADC_SMPR1(ADC1) = 2u << 3 | 2u << 6;        /* 12.5 clocks on IN1, IN2 */
  ADC_JSQR(ADC1) = 1u | 8u << 2 | 1u << 7 | 1u << 9 | 2u << 15;
  ADC_IER(ADC1) = 1u << 6;                    /* JEOSIE */
  ADC_CR(ADC1) |= 1u << 3;                    /* JADSTART */
  NVIC_IPR(18) = 0x10;
  NVIC_ISER0 = 1u << 18;
  /* TIM1 */
  TIM_ARR(TIM1) = ARR_VALUE;
  TIM_RCR(TIM1) = 1u;
  TIM_CCMR1(TIM1) = (6u << 4 | 1u << 3) | (6u << 12 | 1u << 11);
  TIM_CCMR2(TIM1) = (6u << 4 | 1u << 3) | (7u << 12 | 1u << 11);
  TIM_CCR4(TIM1) = ARR_VALUE - 10u;
  TIM_CCER(TIM1) = 0x1555u;                  /* CC1-3 and complements, CC4 */
#ifdef BREAK
  TIM_BDTR(TIM1) = 1u << 15 | 1u << 12 | 170u; /* MOE, BKE, BKP = 0: BRK active low */
  TIM_DIER(TIM1) = 1u << 7;                   /* BIE */
  NVIC_IPR(24) = 0x00;
  NVIC_ISER0 = 1u << 24;
#else
  TIM_BDTR(TIM1) = 1u << 15 | 170u;           /* MOE, DTG 170: (64 + 42) * 2 ticks = 1.247 us */
#endif
  TIM_CR2(TIM1) = 7u << 20;                   /* MMS2 = OC4REF */
  TIM_EGR(TIM1) = 1u;
  TIM_CR1(TIM1) = 1u | 1u << 5 | 1u << 7;     /* CEN, CMS = 1, ARPE */
  for (;;) { __asm volatile("wfi"); }
}
