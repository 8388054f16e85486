/*
 * STM32G474 start-up for the firmware API's board layer: the vector table at 0x08000000 (16 system exceptions and
 * the 102 interrupt lines of RM0440 Table 97; FDCAN1_IT0 at IRQ 21), the reset handler (FPU on through CPACR,
 * .data copied, .bss zeroed, the CCM-SRAM sections initialised, the C++ static constructors run by
 * __libc_init_array, main) and the fault report on USART2.
 */
#include <stdint.h>

#include "board.h"
#include "stm32g474_regs.h"
#include "stm32g474_ll.h"

extern uint32_t _estack;
extern int main(void);
extern void __libc_init_array(void);

/* newlib's __libc_init_array calls _init (crti/crtn, not linked: -nostartfiles) between .preinit_array and
 * .init_array; the constructors themselves are in .init_array (stm32g474.ld) */
void _init(void);
void _fini(void);
void _init(void)
{
}
void _fini(void)
{
}

void Reset_Handler(void);
void Default_Handler(void);
void HardFault_Handler(void);

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

static char *put_str(char *p, const char *s)
{
    while (*s != '\0') {
        *p++ = *s++;
    }
    return p;
}

static char *put_hex(char *p, uint32_t v)
{
    int shift;
    for (shift = 28; shift >= 0; shift -= 4) {
        *p++ = "0123456789abcdef"[(v >> (uint32_t)shift) & 0xFu];
    }
    return p;
}

/* The fault report of the other boards (boards/mps2-an386/startup.c), one line on USART2 --
 *   HIL-FAULT exc=3 pc=0800021c lr=08000a41 cfsr=00010000 hfsr=40000000 mmfar=e000edf8 bfar=e000edf8
 * -- then the core stops here (the bench's heartbeat watch or lockstep timeout ends the run; a debug probe reads
 * the same registers). The virtual board stops at the faulting instruction itself and reports it (exit 3). */
void hil_fault_report(const uint32_t *frame, uint32_t exc_return);
void hil_fault_report(const uint32_t *frame, uint32_t exc_return)
{
    static char line[128];
    uint32_t ipsr;
    char *p = line;
    (void)exc_return;
    __asm__ volatile("mrs %0, ipsr" : "=r"(ipsr));
    p = put_str(p, "HIL-FAULT exc=");
    *p++ = (char)('0' + (ipsr & 0xFu) % 10u);
    p = put_hex(put_str(p, " pc="), frame[6]);
    p = put_hex(put_str(p, " lr="), frame[5]);
    p = put_hex(put_str(p, " cfsr="), SCB->CFSR);
    p = put_hex(put_str(p, " hfsr="), SCB->HFSR);
    p = put_hex(put_str(p, " mmfar="), SCB->MMFAR);
    p = put_hex(put_str(p, " bfar="), SCB->BFAR);
    *p++ = '\n';
    *p = '\0';
    hil_board_console_write(line);
    for (;;) {
    }
}

/* The stacked frame is on the stack the faulting code used (EXC_RETURN bit 2: 0 MSP, 1 PSP). */
__attribute__((naked)) void HardFault_Handler(void)
{
    __asm__ volatile("tst lr, #4\n\t"
                     "ite eq\n\t"
                     "mrseq r0, msp\n\t"
                     "mrsne r0, psp\n\t"
                     "mov r1, lr\n\t"
                     "b hil_fault_report\n\t");
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
