/* Minimal start-up for the board tests: vector table (16 system exceptions + 102 lines), .data/.bss set-up,
 * main. Handlers a test does not define are weak aliases of Default_Handler (an endless loop). */
#include <stdint.h>
extern uint32_t _estack, _sidata, _sdata, _edata, _sbss, _ebss;
int main(void);
void Reset_Handler(void);
void Default_Handler(void) { for (;;) { } }
#define WEAK __attribute__((weak, alias("Default_Handler")))
void NMI_Handler(void) WEAK; void HardFault_Handler(void) WEAK; void MemManage_Handler(void) WEAK;
void BusFault_Handler(void) WEAK; void UsageFault_Handler(void) WEAK; void SVC_Handler(void) WEAK;
void PendSV_Handler(void) WEAK; void SysTick_Handler(void) WEAK;
void IRQ0_Handler(void) WEAK; void IRQ1_Handler(void) WEAK; void IRQ2_Handler(void) WEAK;
void IRQ3_Handler(void) WEAK; void ADC1_2_IRQHandler(void) WEAK; void TIM1_UP_TIM16_IRQHandler(void) WEAK;
void TIM1_CC_IRQHandler(void) WEAK; void USART2_IRQHandler(void) WEAK; void TIM1_BRK_TIM15_IRQHandler(void) WEAK;
void EXTI9_5_IRQHandler(void) WEAK; void TIM4_IRQHandler(void) WEAK;
__attribute__((section(".isr_vector"), used)) const void *const vectors[16 + 102] = {
  [0] = &_estack, [1] = Reset_Handler, [2] = NMI_Handler, [3] = HardFault_Handler, [4] = MemManage_Handler,
  [5] = BusFault_Handler, [6] = UsageFault_Handler, [11] = SVC_Handler, [14] = PendSV_Handler,
  [15] = SysTick_Handler, [16 + 0] = IRQ0_Handler, [16 + 1] = IRQ1_Handler, [16 + 2] = IRQ2_Handler,
  [16 + 3] = IRQ3_Handler, [16 + 18] = ADC1_2_IRQHandler, [16 + 23] = EXTI9_5_IRQHandler,
  [16 + 24] = TIM1_BRK_TIM15_IRQHandler, [16 + 25] = TIM1_UP_TIM16_IRQHandler,
  [16 + 27] = TIM1_CC_IRQHandler, [16 + 30] = TIM4_IRQHandler, [16 + 38] = USART2_IRQHandler,
};
void Reset_Handler(void) {
  uint32_t *src = &_sidata, *dst = &_sdata;
  while (dst < &_edata) { *dst++ = *src++; }
  for (dst = &_sbss; dst < &_ebss;) { *dst++ = 0; }
  main();
  for (;;) { __asm volatile("wfi"); }
}
