/* Register addresses of the board tests, from RM0440 and PM0214. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
#define SCB_CPACR REG(0xE000ED88u)
#define SCB_AIRCR REG(0xE000ED0Cu)
#define SCB_ICSR REG(0xE000ED04u)
#define SCB_SHPR3 REG(0xE000ED20u)
#define SCB_CFSR REG(0xE000ED28u)
#define SYST_CSR REG(0xE000E010u)
#define SYST_RVR REG(0xE000E014u)
#define SYST_CVR REG(0xE000E018u)
#define NVIC_ISER0 REG(0xE000E100u)
#define NVIC_ISPR0 REG(0xE000E200u)
#define NVIC_IPR(n) (*(volatile uint8_t *)(0xE000E400u + (n)))
#define DEMCR REG(0xE000EDFCu)
#define DWT_CTRL REG(0xE0001000u)
#define DWT_CYCCNT REG(0xE0001004u)
#define RCC_CR REG(0x40021000u)
#define RCC_CFGR REG(0x40021008u)
#define RCC_PLLCFGR REG(0x4002100Cu)
#define RCC_AHB2ENR REG(0x4002104Cu)
#define RCC_APB1ENR1 REG(0x40021058u)
#define RCC_APB2ENR REG(0x40021060u)
#define RCC_CCIPR REG(0x40021088u)
#define PWR_CR1 REG(0x40007000u)
#define PWR_SR2 REG(0x40007014u)
#define PWR_CR5 REG(0x40007080u)
#define FLASH_ACR REG(0x40022000u)
#define GPIOA_MODER REG(0x48000000u)
#define GPIOA_ODR REG(0x48000014u)
#define GPIOA_BSRR REG(0x48000018u)
#define USART2_CR1 REG(0x40004400u)
#define USART2_BRR REG(0x4000440Cu)
#define USART2_ISR REG(0x4000441Cu)
#define USART2_TDR REG(0x40004428u)
#define TIM1 0x40012C00u
#define TIM_CR1(t) REG((t) + 0x00u)
#define TIM_CR2(t) REG((t) + 0x04u)
#define TIM_SMCR(t) REG((t) + 0x08u)
#define TIM_DIER(t) REG((t) + 0x0Cu)
#define TIM_SR(t) REG((t) + 0x10u)
#define TIM_EGR(t) REG((t) + 0x14u)
#define TIM_CCMR1(t) REG((t) + 0x18u)
#define TIM_CCMR2(t) REG((t) + 0x1Cu)
#define TIM_CCER(t) REG((t) + 0x20u)
#define TIM_CNT(t) REG((t) + 0x24u)
#define TIM_PSC(t) REG((t) + 0x28u)
#define TIM_ARR(t) REG((t) + 0x2Cu)
#define TIM_RCR(t) REG((t) + 0x30u)
#define TIM_CCR1(t) REG((t) + 0x34u)
#define TIM_CCR2(t) REG((t) + 0x38u)
#define TIM_CCR3(t) REG((t) + 0x3Cu)
#define TIM_CCR4(t) REG((t) + 0x40u)
#define TIM_BDTR(t) REG((t) + 0x44u)
#define TIM3 0x40000400u
#define ADC1 0x50000000u
#define ADC2 0x50000100u
#define ADC_ISR(a) REG((a) + 0x00u)
#define ADC_IER(a) REG((a) + 0x04u)
#define ADC_CR(a) REG((a) + 0x08u)
#define ADC_CFGR(a) REG((a) + 0x0Cu)
#define ADC_SMPR1(a) REG((a) + 0x14u)
#define ADC_SQR1(a) REG((a) + 0x30u)
#define ADC_DR(a) REG((a) + 0x40u)
#define ADC_JSQR(a) REG((a) + 0x4Cu)
#define ADC_JDR1(a) REG((a) + 0x80u)
#define ADC_JDR2(a) REG((a) + 0x84u)
#define ADC12_CCR REG(0x50000308u)

/* 170 MHz from HSE 24 MHz: PLLM /6, PLLN x85, PLLR /2 (RM0440 7.4.4), boost mode, 4 wait states */
static inline void clock_170mhz(void) {
  PWR_CR5 &= ~(1u << 8);                     /* R1MODE = 0: boost */
  FLASH_ACR = (FLASH_ACR & ~0xFu) | 4u;
  while ((FLASH_ACR & 0xFu) != 4u) { }
  RCC_CR |= 1u << 16;                        /* HSEON */
  while (!(RCC_CR & (1u << 17))) { }         /* HSERDY */
  RCC_PLLCFGR = 3u | (5u << 4) | (85u << 8) | (1u << 24); /* HSE, M=6, N=85, R=2, PLLREN */
  RCC_CR |= 1u << 24;
  while (!(RCC_CR & (1u << 25))) { }         /* PLLRDY */
  RCC_CFGR = (RCC_CFGR & ~0xF3u) | (8u << 4) | 3u; /* AHB /2 while switching, SW = PLL */
  while ((RCC_CFGR & 0xCu) != 0xCu) { }      /* SWS = PLL */
  RCC_CFGR &= ~0xF0u;                        /* AHB /1 */
  while (PWR_SR2 & (1u << 10)) { }
}
