/*
 * STM32G474 start-up for the firmware API's board layer: the vector table at 0x08000000 (16 system exceptions and
 * the 102 interrupt lines of RM0440 Table 97; FDCAN1_IT0 at IRQ 21), the reset handler (FPU on through CPACR,
 * .data copied, .bss zeroed, the CCM-SRAM sections initialised, the C++ static constructors run by
 * __libc_init_array, main) and the fault report on USART2.
 */
#include <stdint.h>

#include "board.h"
#include "hil_cortexm_startup.h"
#include "stm32g474_regs.h"
#include "stm32g474_ll.h"

extern uint32_t _estack;

void Reset_Handler(void);
void Default_Handler(void);

void Reset_Handler(void)
{
    g4_reset_init(); /* the FPU on, .data and .ccmdata copied, .bss and .ccmbss zeroed */
    SystemInit();
    __libc_init_array(); /* after the FPU is on: a constructor may compute in float */
    (void)main();
    for (;;) {
        __WFI();
    }
}

void Default_Handler(void)
{
    for (;;) {
    }
}

/* The fault report of the other boards (boards/mps2-an386/startup.c), one line on USART2 (hil_cortexm_startup.h); then
 * the core stops here (the bench's heartbeat watch or lockstep timeout ends the run; a debug probe reads the same
 * registers). The virtual board stops at the faulting instruction itself and reports it (exit 3). */
void hil_fault_report(const uint32_t *frame, uint32_t exc_return)
{
    static char line[128];
    (void)exc_return;
    (void)hil_fault_line(line, frame);
    hil_board_console_write(line);
    for (;;) {
    }
}

typedef void (*vector_t)(void);

#define D Default_Handler
#define D8 D, D, D, D, D, D, D, D

__attribute__((section(".isr_vector"), used)) const vector_t hil_vectors[16 + 102] = {
    (vector_t)(uintptr_t)&_estack, /* initial stack pointer */
    Reset_Handler,
    D,                 /* NMI */
    HardFault_Handler, /* HardFault */
    HardFault_Handler, /* MemManage (not enabled in SHCSR: escalates to HardFault) */
    HardFault_Handler, /* BusFault */
    HardFault_Handler, /* UsageFault */
    0, 0, 0, 0,
    D, /* SVCall */
    D, /* DebugMon */
    0,
    D, /* PendSV */
    D, /* SysTick */
    D8, D8, D, D, D, D, D, /* IRQ 0 .. 20 */
    FDCAN1_IT0_IRQHandler, /* IRQ 21 */
    D,                     /* IRQ 22: FDCAN1_IT1 (every interrupt group on line 0) */
    D8, D8, D8, D8, D8, D8, D8, D8, D8, D, D, D, D, D, D, D, /* IRQ 23 .. 101 */
};
