/* mps2-an386 start-up: vector table, reset handler (copy .data, zero .bss, enable the FPU via CPACR, run the
 * static constructors of C++ global objects), fault handler. */
#include <stdint.h>

#include "board.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
extern int main(void);
extern void __libc_init_array(void);

/* newlib's __libc_init_array calls _init (crti/crtn, not linked: -nostartfiles) between .preinit_array and
 * .init_array; the constructors themselves are in .init_array (mps2-an386.ld) */
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

#define SCB_CFSR (*(volatile uint32_t *)0xE000ED28u)
#define SCB_HFSR (*(volatile uint32_t *)0xE000ED2Cu)
#define SCB_MMFAR (*(volatile uint32_t *)0xE000ED34u)
#define SCB_BFAR (*(volatile uint32_t *)0xE000ED38u)

static void semihost_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
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

/* The fault report (called by HardFault_Handler with the stacked exception frame r0-r3, r12, lr, pc, xpsr).
 * When the host asked for it (hil_board_cfg.fault_exit: QEMU runs with semihosting) it writes one line to the
 * semihosting console (QEMU's stderr) --
 *   HIL-FAULT exc=3 pc=0000021c lr=00000a41 cfsr=00010000 hfsr=40000000 mmfar=e000edf8 bfar=e000edf8
 * -- which the host turns into "target HardFault at pc 0x... (function+0xOFF), CFSR ..." (src/pmsm_hil/sim_target/qemu.py),
 * then ends QEMU with exit code HIL_BOARD_FAULT_EXIT_BASE + the exception number (3 HardFault, 4 MemManage,
 * 5 BusFault, 6 UsageFault): an Arm semihosting SYS_EXIT_EXTENDED, reason ApplicationExit, so the host tells a
 * fault from a hang and from a dead QEMU. Otherwise it stops here and the host's lockstep timeout ends the run. */
void hil_fault_report(const uint32_t *frame, uint32_t exc_return);
void hil_fault_report(const uint32_t *frame, uint32_t exc_return)
{
    (void)exc_return;
    if (hil_board_cfg.magic == HIL_BOARD_CFG_MAGIC && hil_board_cfg.fault_exit != 0u) {
        static char line[128];
        uint32_t ipsr;
        uint32_t args[2];
        char *p = line;
        __asm__ volatile("mrs %0, ipsr" : "=r"(ipsr));
        p = put_str(p, "HIL-FAULT exc=");
        *p++ = (char)('0' + (ipsr & 0xFu) % 10u);
        p = put_hex(put_str(p, " pc="), frame[6]);
        p = put_hex(put_str(p, " lr="), frame[5]);
        p = put_hex(put_str(p, " cfsr="), SCB_CFSR);
        p = put_hex(put_str(p, " hfsr="), SCB_HFSR);
        p = put_hex(put_str(p, " mmfar="), SCB_MMFAR);
        p = put_hex(put_str(p, " bfar="), SCB_BFAR);
        *p++ = '\n';
        *p = '\0';
        semihost_call(0x04u, line); /* SYS_WRITE0 */
        args[0] = 0x20026u;         /* ADP_Stopped_ApplicationExit: args[1] is the exit code */
        args[1] = HIL_BOARD_FAULT_EXIT_BASE + (ipsr & 0x1FFu);
        semihost_call(0x20u, args); /* SYS_EXIT_EXTENDED */
    }
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
