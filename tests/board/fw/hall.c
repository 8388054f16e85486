/* Hall test: 170 MHz, TIM1 centre-aligned at 20 kHz (the carrier the run side paces), hall A/B/C on PB6/PB7/PB8
 * (inputs), EXTI lines 6-8 on port B (SYSCFG EXTICR2/3), both edges, EXTI9_5 interrupt. The handler counts the
 * edges, stamps each with DWT CYCCNT and records the sector code C<<2 | B<<1 | A read from GPIOB IDR. */
#include "regs.h"
#define ARR_VALUE 4250u
#define SYSCFG_EXTICR2 REG(0x4001000Cu)
#define SYSCFG_EXTICR3 REG(0x40010010u)
#define EXTI_IMR1 REG(0x40010400u)
#define EXTI_RTSR1 REG(0x40010408u)
#define EXTI_FTSR1 REG(0x4001040Cu)
#define EXTI_PR1 REG(0x40010414u)
#define GPIOB_MODER REG(0x48000400u)
#define GPIOB_IDR REG(0x48000410u)
#define HALL_PINS (7u << 6)
#define KEEP 256u
volatile uint32_t edges, codes_n, first_code;
volatile uint8_t codes[KEEP];
volatile uint32_t stamps[KEEP];

void EXTI9_5_IRQHandler(void) {
  uint32_t pr = EXTI_PR1 & HALL_PINS;
  uint32_t at = DWT_CYCCNT;
  EXTI_PR1 = pr;
  edges += (uint32_t)__builtin_popcount(pr);
  codes[codes_n % KEEP] = (uint8_t)(GPIOB_IDR >> 6 & 7u);
  stamps[codes_n % KEEP] = at;
  ++codes_n;
}

int main(void) {
  SCB_CPACR |= 0xFu << 20;
  clock_170mhz();
  DEMCR |= 1u << 24;
  DWT_CTRL |= 1u;
  RCC_AHB2ENR |= 1u << 1;                    /* GPIOBEN */
  RCC_APB2ENR |= 1u << 0 | 1u << 11;         /* SYSCFGEN, TIM1EN */
  GPIOB_MODER &= ~(0x3Fu << 12);             /* PB6-8 inputs */
  first_code = GPIOB_IDR >> 6 & 7u;
  SYSCFG_EXTICR2 = 1u << 8 | 1u << 12;       /* EXTI6, EXTI7: port B */
  SYSCFG_EXTICR3 = 1u << 0;                  /* EXTI8: port B */
  EXTI_RTSR1 |= HALL_PINS;
  EXTI_FTSR1 |= HALL_PINS;
  EXTI_IMR1 |= HALL_PINS;
  NVIC_ISER0 = 1u << 23;                     /* EXTI9_5 */
  TIM_ARR(TIM1) = ARR_VALUE;
  TIM_RCR(TIM1) = 1u;
  TIM_EGR(TIM1) = 1u;
  TIM_CR1(TIM1) = 1u | 1u << 5 | 1u << 7;    /* CEN, CMS = 1, ARPE */
  for (;;) { __asm volatile("wfi"); }
}
