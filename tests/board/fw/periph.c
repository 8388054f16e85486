/* More peripherals on the virtual board: a DMA memory-to-memory copy polled on TCIF, a CORDIC sine, then the window
 * watchdog left unrefreshed (its early wakeup interrupt on IRQ 0, then the reset) or, with -DUSE_IWDG, the
 * independent watchdog started as HAL_IWDG_Init starts it and never refreshed. */
#include "regs.h"
volatile uint32_t src[16], dst[16], dma_ok, cordic_sin, cordic_cos, ewi_count, wwdg_cr, iwdg_sr_polls;
void IRQ0_Handler(void) { REG(0x40002C08u) = 0; ++ewi_count; wwdg_cr = REG(0x40002C00u); }
int main(void) {
  for (uint32_t i = 0; i < 16; ++i) { src[i] = i * 0x01010101u + 7u; }
  REG(0x40021048u) |= 0xFu;                           /* RCC_AHB1ENR: DMA1, DMA2, DMAMUX1, CORDIC */
  REG(0x40020008u) = 0;                               /* DMA1 CCR1 off, then CNDTR1, CPAR1, CMAR1 */
  REG(0x4002000Cu) = 16;
  REG(0x40020010u) = (uint32_t)src;
  REG(0x40020014u) = (uint32_t)dst;
  REG(0x40020008u) = (1u << 14) | (2u << 10) | (2u << 8) | (1u << 7) | (1u << 6) | 1u; /* MEM2MEM, 32-bit, INC, EN */
  while (!(REG(0x40020000u) & 2u)) { }                /* TCIF1 */
  dma_ok = 1;
  for (uint32_t i = 0; i < 16; ++i) { if (dst[i] != src[i]) { dma_ok = 0; } }
  REG(0x40020C00u) = 1u | (6u << 4) | (1u << 19);     /* CORDIC: sine, 24 iterations, two results */
  REG(0x40020C04u) = 0x15555555u;                     /* 1/6 in q1.31: 30 degrees */
  cordic_sin = REG(0x40020C08u);
  cordic_cos = REG(0x40020C08u);
#ifdef USE_IWDG
  REG(0x40003000u) = 0xCCCCu;                         /* start, unlock, PR /4, RLR 100, wait SR, refresh */
  REG(0x40003000u) = 0x5555u;
  REG(0x40003004u) = 0u;
  REG(0x40003008u) = 100u;
  while (REG(0x4000300Cu)) { ++iwdg_sr_polls; }
  REG(0x40003000u) = 0xAAAAu;
#else
  RCC_APB1ENR1 |= 1u << 11;                           /* WWDGEN */
  NVIC_ISER0 = 1u;
  REG(0x40002C04u) = (1u << 9) | (3u << 11) | 0x7Fu;  /* EWI, WDGTB 3, W 0x7F */
  REG(0x40002C00u) = 0x80u | 0x7Fu;                   /* WDGA, T 0x7F */
#endif
  for (;;) { __asm volatile("wfi"); }
}
