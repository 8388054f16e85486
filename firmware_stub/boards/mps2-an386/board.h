/* mps2-an386 board layer: CMSDK UART0 (RX interrupt), SysTick as the execution clock, the frame loop. */
#ifndef HIL_BOARD_MPS2_AN386_H
#define HIL_BOARD_MPS2_AN386_H

#include <stdint.h>

/* Written by the host before reset through QEMU's loader device (`-device loader,addr=&hil_board_cfg`):
 * lets the firmware turn SysTick ticks into the execution-time estimate it reports in exec_time_ns. */
typedef struct {
    uint32_t magic;        /* HIL_BOARD_CFG_MAGIC when written */
    uint32_t mcu_clock_hz; /* clock of the estimate (`hil run --mcu-clock`, default 168 MHz) */
    uint32_t ns_per_insn;  /* QEMU -icount: 2^shift ns of virtual time per instruction */
    uint32_t cpi_milli;    /* cycle model: cycles per instruction x 1000 */
} hil_board_cfg_t;

#define HIL_BOARD_CFG_MAGIC 0x48494C43u /* "HILC" */
#define HIL_BOARD_SYSCLK_HZ 25000000u   /* mps2-an386 SYSCLK: the SysTick (CLKSOURCE = core clock) */

extern volatile hil_board_cfg_t hil_board_cfg;

void UART0_RX_Handler(void);

#endif
