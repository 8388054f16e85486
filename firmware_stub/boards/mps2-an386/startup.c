/* mps2-an386 start-up: vector table, reset handler (copy .data, zero .bss, enable the FPU via CPACR, run the
 * static constructors of C++ global objects), fault handler. */
#include <stdint.h>

#include "board.h"
#include "hil_cortexm_startup.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;

void Reset_Handler(void);
void Default_Handler(void);

#define CPACR (*(volatile uint32_t *)0xE000ED88u)

void Reset_Handler(void)
{
    uint32_t *src = &_sidata;
    uint32_t *dst = &_sdata;
    while (dst < &_edata) {
        *dst++ = *src++;
    }
    for (dst = &_sbss; dst < &_ebss; ++dst) {
        *dst = 0u;
    }
    CPACR |= (0xFu << 20); /* CP10, CP11 full access: the single-precision FPU */
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    __libc_init_array(); /* after the FPU is on: a constructor may compute in float */
    (void)main();
    for (;;) {
    }
}

void Default_Handler(void)
{
    for (;;) {
    }
}

static void semihost_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
}

/* The fault report (called by HardFault_Handler with the stacked exception frame, hil_cortexm_startup.h). When the host
 * asked for it (hil_board_cfg.fault_exit: QEMU runs with semihosting) it writes the line to the semihosting console
 * (QEMU's stderr), then ends QEMU with exit code HIL_BOARD_FAULT_EXIT_BASE + the exception number (3 HardFault, 4 MemManage,
 * 5 BusFault, 6 UsageFault): an Arm semihosting SYS_EXIT_EXTENDED, reason ApplicationExit, so the host tells a
 * fault from a hang and from a dead QEMU. Otherwise it stops here and the host's lockstep timeout ends the run. */
void hil_fault_report(const uint32_t *frame, uint32_t exc_return)
{
    (void)exc_return;
    if (hil_board_cfg.magic == HIL_BOARD_CFG_MAGIC && hil_board_cfg.fault_exit != 0u) {
        static char line[128];
        uint32_t args[2];
        const uint32_t ipsr = hil_fault_line(line, frame);
        semihost_call(0x04u, line); /* SYS_WRITE0 */
        args[0] = 0x20026u;         /* ADP_Stopped_ApplicationExit: args[1] is the exit code */
        args[1] = HIL_BOARD_FAULT_EXIT_BASE + (ipsr & 0x1FFu);
        semihost_call(0x20u, args); /* SYS_EXIT_EXTENDED */
    }
    for (;;) {
    }
}

typedef void (*vector_t)(void);

__attribute__((section(".vectors"), used)) const vector_t hil_vectors[16 + 16] = {
    (vector_t)(uintptr_t)&_estack, /* initial stack pointer */
    Reset_Handler,
    Default_Handler,  /* NMI */
    HardFault_Handler,
    HardFault_Handler, /* MemManage */
    HardFault_Handler, /* BusFault */
    HardFault_Handler, /* UsageFault */
    0, 0, 0, 0,
    Default_Handler, /* SVCall */
    Default_Handler, /* DebugMon */
    0,
    Default_Handler, /* PendSV */
    Default_Handler, /* SysTick */
    UART0_RX_Handler, /* IRQ 0: UART0 RX */
    Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler,
    Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler,
    Default_Handler, Default_Handler, Default_Handler,
};
