/* FDCAN kernel clock test: 170 MHz from HSE 24 MHz, FDCAN1's kernel clock from RCC CCIPR.FDCANSEL = SEL (0 HSE,
 * 1 PLL Q: PLLQEN set with QEN, Q = /2 -> 170 MHz, 2 PCLK1 = 170 MHz), nominal bit timing NBRP/34 time quanta
 * (NBRP 4: 1 Mbit/s at 170 MHz), data bit timing DBRP/34 time quanta (DBRP 0: 5 Mbit/s) with FD and bit-rate
 * switching when FD is defined (NO_HSE: the core stays on HSI16, the HSE off); then the controller leaves initialisation and the core sleeps.
 * PPRE1_AFTER: once on the bus, the APB1 prescaler goes to /2 (PCLK1 85 MHz: with SEL 2 FDCAN1's kernel clock halves). */
#include "regs.h"
#define FDCAN1_DBTP REG(0x4000640Cu)
#define FDCAN1_CCCR REG(0x40006418u)
#define FDCAN1_NBTP REG(0x4000641Cu)
#ifndef SEL
#define SEL 2
#endif
#ifndef NBRP
#define NBRP 4
#endif
#ifndef DBRP
#define DBRP 0
#endif
volatile uint32_t on_bus;

int main(void) {
  SCB_CPACR |= 0xFu << 20;
#ifndef NO_HSE
  clock_170mhz();
#endif
#ifdef QEN
  RCC_PLLCFGR |= 1u << 20;                    /* PLLQEN, PLLQ = /2 */
#endif
  RCC_APB1ENR1 |= 1u << 25;                   /* FDCANEN */
  RCC_CCIPR = (RCC_CCIPR & ~(3u << 24)) | (uint32_t)SEL << 24;
  FDCAN1_CCCR |= 1u << 1;                     /* CCE (INIT is set from reset) */
  FDCAN1_NBTP = 5u << 25 | (uint32_t)NBRP << 16 | 26u << 8 | 5u;
  FDCAN1_DBTP = (uint32_t)DBRP << 16 | 25u << 8 | 6u << 4 | 6u;
#ifdef FD
  FDCAN1_CCCR |= 1u << 8 | 1u << 9;           /* FDOE, BRSE */
#endif
  FDCAN1_CCCR &= ~1u;                         /* leave INIT: on the bus */
  on_bus = 1;
#ifdef PPRE1_AFTER
  RCC_CFGR = (RCC_CFGR & ~(7u << 8)) | 4u << 8; /* PPRE1 = /2 */
  on_bus = 2;
#endif
  for (;;) { __asm volatile("wfi"); }
}
