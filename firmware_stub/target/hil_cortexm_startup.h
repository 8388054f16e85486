/*
 * What the start-up files of the Cortex-M boards (boards/mps2-an386/startup.c, boards/stm32g474/startup.c) share:
 * the _init/_fini that newlib's __libc_init_array calls (the C++ static constructors), and the fault report: the
 * HardFault handler that hands the exception frame the core stacked (r0-r3, r12, lr, pc, xpsr) to the board's
 * hil_fault_report, and the one line that reports it --
 *   HIL-FAULT exc=3 pc=0800021c lr=08000a41 cfsr=00010000 hfsr=40000000 mmfar=e000edf8 bfar=e000edf8
 * -- from that frame and the ARMv7-M fault registers, which the host turns into "target HardFault at pc 0x...
 * (function+0xOFF), CFSR ..." (src/pmsm_hil/sim_target/qemu.py). Included by a board's start-up file only.
 */
#ifndef HIL_CORTEXM_STARTUP_H
#define HIL_CORTEXM_STARTUP_H

#include <stdint.h>

extern int main(void);
extern void __libc_init_array(void);

/* newlib's __libc_init_array calls _init (crti/crtn, not linked: -nostartfiles) between .preinit_array and
 * .init_array; the constructors themselves are in .init_array (the board's linker script) */
void _init(void);
void _fini(void);
void _init(void)
{
}
void _fini(void)
{
}

/* the board's report: exc_return is the handler's LR (EXC_RETURN) */
void hil_fault_report(const uint32_t *frame, uint32_t exc_return);
void HardFault_Handler(void);

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

static inline char *hil_fault_put_str(char *p, const char *s)
{
    while (*s != '\0') {
        *p++ = *s++;
    }
    return p;
}

static inline char *hil_fault_put_hex(char *p, const char *label, uint32_t v)
{
    int shift;
    p = hil_fault_put_str(p, label);
    for (shift = 28; shift >= 0; shift -= 4) {
        *p++ = "0123456789abcdef"[(v >> (uint32_t)shift) & 0xFu];
    }
    return p;
}

/* Write the report of the exception in progress, '\n' and NUL included, into `line` (at least 100 bytes); returns
 * the exception number (IPSR). */
static inline uint32_t hil_fault_line(char *line, const uint32_t *frame)
{
    uint32_t ipsr;
    char *p = line;
    __asm__ volatile("mrs %0, ipsr" : "=r"(ipsr));
    p = hil_fault_put_str(p, "HIL-FAULT exc=");
    *p++ = (char)('0' + (ipsr & 0xFu) % 10u);
    p = hil_fault_put_hex(p, " pc=", frame[6]);
    p = hil_fault_put_hex(p, " lr=", frame[5]);
    p = hil_fault_put_hex(p, " cfsr=", *(volatile uint32_t *)0xE000ED28u);
    p = hil_fault_put_hex(p, " hfsr=", *(volatile uint32_t *)0xE000ED2Cu);
    p = hil_fault_put_hex(p, " mmfar=", *(volatile uint32_t *)0xE000ED34u);
    p = hil_fault_put_hex(p, " bfar=", *(volatile uint32_t *)0xE000ED38u);
    *p++ = '\n';
    *p = '\0';
    return ipsr;
}

#endif
