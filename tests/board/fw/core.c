/* Core test: clock set-up to 170 MHz, SysTick at 1 kHz with an FP-using handler, nested and tail-chained
 * interrupts by priority, DWT CYCCNT, a console line on USART2. Results in variables the test reads. */
#include "regs.h"
volatile uint32_t ticks, fp_errors, order[8], n_order, cyc_a, cyc_b, sysclk_ok, done;
volatile float tick_acc;

void SysTick_Handler(void) {
  float a = (float)ticks * 1.25f, b = a * a - 3.5f, c = b / (a + 1.0f);
  tick_acc = tick_acc + c * 0.0f + a - a;    /* clobbers s-registers */
  ++ticks;
}
static void note(uint32_t v) { if (n_order < 8) { order[n_order++] = v; } }
void IRQ0_Handler(void) { note(0); NVIC_ISPR0 = (1u << 1) | (1u << 2); note(10); } /* 1 preempts, 2 tail-chains */
void IRQ1_Handler(void) { note(1); }
void IRQ2_Handler(void) { note(2); }
#ifdef RAM_CODE
/* copied to SRAM with .data by the start-up code: the core first fetches from SRAM when main calls it, and SysTick
 * interrupts it there */
__attribute__((section(".data.ram_code"), noinline, long_call)) static uint32_t ram_twice(uint32_t v) {
  return 2u * v;
}
volatile uint32_t ram_sum;
#endif
static void puts2(const char *s) { while (*s) { while (!(USART2_ISR & (1u << 7))) { } USART2_TDR = (uint8_t)*s++; } }

int main(void) {
  SCB_CPACR |= 0xFu << 20;
  clock_170mhz();
  sysclk_ok = (RCC_CFGR & 0xCu) == 0xCu;
  RCC_APB1ENR1 |= 1u << 17;
  USART2_BRR = 170000000u / 115200u;
  USART2_CR1 = 1u | (1u << 3);
  puts2("board core test\r\n");
  DEMCR |= 1u << 24;
  DWT_CYCCNT = 0;
  DWT_CTRL |= 1u;
  cyc_a = DWT_CYCCNT;
  for (volatile int i = 0; i < 100; ++i) { }
  cyc_b = DWT_CYCCNT;
  NVIC_IPR(0) = 0x80; NVIC_IPR(1) = 0x40; NVIC_IPR(2) = 0xC0;
  NVIC_ISER0 = 7u;
  NVIC_ISPR0 = 1u;
  SYST_RVR = 170000u - 1u;
  SYST_CVR = 0;
  SYST_CSR = 7u;                              /* HCLK, TICKINT, ENABLE */
  float x = 0.0f;
  for (uint32_t i = 0; i < 200000u; ++i) {
    x += 0.25f;
    if (x != 0.25f * (float)(i + 1u)) { ++fp_errors; }
  }
#ifdef RAM_CODE
  for (uint32_t i = 0; i < 100000u; ++i) { ram_sum += ram_twice(i); }
#endif
  done = 1;
  for (;;) { __asm volatile("wfi"); }
}
