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
    uint32_t transport;    /* HIL_BOARD_UART (WFI on the UART RX interrupt) or HIL_BOARD_MAILBOX (PSRAM + doorbells) */
    uint32_t fault_exit;   /* 1: a fault ends QEMU through semihosting (startup.c HardFault_Handler) */
} hil_board_cfg_t;

/* QEMU's exit code after a fault: this + the exception number (3 HardFault .. 6 UsageFault) */
#define HIL_BOARD_FAULT_EXIT_BASE 64u

#define HIL_BOARD_UART 0u
#define HIL_BOARD_MAILBOX 1u

/* Mailbox in the board's PSRAM (QEMU machine RAM at 0x21000000, shared with the host through
 * -object memory-backend-file,share=on): one request, one reply, each a list of frames
 * (u32 LE id, u8 fd, u8 len, len bytes). The host writes its buffer and length, then its sequence word in
 * one 32-bit store; the target answers with its buffer and length, then echoes the sequence word. */
#define HIL_MBOX_BASE 0x21000000u
#define HIL_MBOX_H2T_SEQ 0x000u
#define HIL_MBOX_H2T_LEN 0x004u
#define HIL_MBOX_T2H_SEQ 0x008u
#define HIL_MBOX_T2H_LEN 0x00Cu
#define HIL_MBOX_H2T_BUF 0x040u
#define HIL_MBOX_T2H_BUF 0x440u
#define HIL_MBOX_BUF_SIZE 0x400u
/* doorbells: NUL-terminated paths of two host FIFOs (host-to-target, target-to-host), one byte rung per
 * request and per reply, read and written by the firmware with Arm semihosting calls */
#define HIL_MBOX_H2T_PATH 0x840u
#define HIL_MBOX_T2H_PATH 0x940u
#define HIL_MBOX_PATH_SIZE 0x100u

#define HIL_BOARD_CFG_MAGIC 0x48494C43u /* "HILC" */
#define HIL_BOARD_SYSCLK_HZ 25000000u   /* mps2-an386 SYSCLK: the SysTick (CLKSOURCE = core clock) */

extern volatile hil_board_cfg_t hil_board_cfg;

void UART0_RX_Handler(void);

#endif
