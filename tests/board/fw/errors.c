/* Error test: FAULT_READ reads an address no memory answers (a precise BusFault); UNMODELLED writes COMP1_CSR,
 * which the board does not model; UNMODELLED_REGISTER an offset of TIM1 the model lacks; BAD_RETURN returns from
 * a handler with a corrupt EXC_RETURN; UNMODELLED_DWT reads an offset of the DWT the board lacks (its reads are C: the
 * Python reference names the register). */
#include "regs.h"
volatile uint32_t sink;
__attribute__((noinline)) void touch_nothing(void) { sink = REG(0x9F000000u); }
__attribute__((noinline)) void touch_comp(void) { REG(0x40010200u) = 1u; }
__attribute__((noinline)) void touch_tim1_reserved(void) { REG(0x40012C70u) = 1u; }
__attribute__((noinline)) void touch_dwt_reserved(void) { sink = REG(0xE0001200u); }
void SVC_Handler(void) { __asm volatile("ldr r0, =0xFFFFFFF5\n bx r0"); }
int main(void) {
#if defined(FAULT_READ)
  touch_nothing();
#elif defined(UNMODELLED)
  touch_comp();
#elif defined(UNMODELLED_REGISTER)
  touch_tim1_reserved();
#elif defined(UNMODELLED_DWT)
  sink = REG(0xE0001004u);                    /* CYCCNT: answered in C */
  touch_dwt_reserved();
#elif defined(BAD_RETURN)
  __asm volatile("svc 0");
#endif
  for (;;) { __asm volatile("wfi"); }
}
