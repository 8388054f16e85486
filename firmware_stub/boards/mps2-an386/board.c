/* mps2-an386 board layer: CMSDK APB UART0 at 0x40004000 with an RX interrupt and WFI, the serial framing
 * (COBS + CRC-16, hil_serial.c) around the target core, SysTick as the execution clock. */
#include <stddef.h>
#include <stdint.h>

#include "board.h"
#include "hil_serial.h"
#include "hil_target_core.h"

#define UART0_BASE 0x40004000u
#define UART_DATA (*(volatile uint32_t *)(UART0_BASE + 0x00u))
#define UART_STATE (*(volatile uint32_t *)(UART0_BASE + 0x04u))
#define UART_CTRL (*(volatile uint32_t *)(UART0_BASE + 0x08u))
#define UART_INTCLEAR (*(volatile uint32_t *)(UART0_BASE + 0x0Cu))
#define UART_BAUDDIV (*(volatile uint32_t *)(UART0_BASE + 0x10u))
#define STATE_TXFULL 0x1u
#define STATE_RXFULL 0x2u
#define CTRL_TXEN 0x1u
#define CTRL_RXEN 0x2u
#define CTRL_RXINTEN 0x8u
#define INT_RX 0x2u

#define NVIC_ISER0 (*(volatile uint32_t *)0xE000E100u)
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

#define RX_RING 512u /* power of two */

__attribute__((section(".noinit"))) volatile hil_board_cfg_t hil_board_cfg;

static volatile uint8_t rx_ring[RX_RING];
static volatile uint32_t rx_head; /* written by the ISR */
static uint32_t rx_tail;          /* written by the main loop */
static hil_serial_t serial;

static void uart_drain(void)
{
    while (UART_STATE & STATE_RXFULL) {
        const uint8_t b = (uint8_t)UART_DATA;
        const uint32_t h = rx_head;
        if (h - rx_tail < RX_RING) { /* full: the byte is lost (the host sees a framing error) */
            rx_ring[h & (RX_RING - 1u)] = b;
            rx_head = h + 1u;
        }
    }
}

/* Clear first, then drain: a byte that arrives after the last read raises the interrupt again (clearing
 * after the drain could swallow that interrupt and leave the byte unread, the UART stalled). */
void UART0_RX_Handler(void)
{
    UART_INTCLEAR = INT_RX;
    uart_drain();
}

static void uart_write(const uint8_t *p, size_t n)
{
    size_t i;
    for (i = 0u; i < n; ++i) {
        while (UART_STATE & STATE_TXFULL) {
        }
        UART_DATA = p[i];
    }
}

uint32_t hil_board_clock(void)
{
    return 0x00FFFFFFu - (SYST_CVR & 0x00FFFFFFu);
}

/* SysTick runs at SYSCLK on virtual time; under -icount each instruction takes ns_per_insn of it, so
 * ticks -> instructions -> cycles (cpi) -> ns at mcu_clock_hz. 0 ("not measured") if the host did not
 * write the configuration. */
uint32_t hil_board_exec_ns(uint32_t t0, uint32_t t1)
{
    const uint64_t ticks = (uint64_t)((t1 - t0) & 0x00FFFFFFu);
    uint64_t den;
    uint64_t num;
    if (hil_board_cfg.magic != HIL_BOARD_CFG_MAGIC || hil_board_cfg.mcu_clock_hz == 0u ||
        hil_board_cfg.ns_per_insn == 0u) {
        return 0u;
    }
    /* ns = ticks * (1e9 / SYSCLK) / ns_per_insn * cpi / mcu_clock * 1e9 */
    num = ticks * (1000000000u / HIL_BOARD_SYSCLK_HZ) * hil_board_cfg.cpi_milli * 1000000u;
    den = (uint64_t)hil_board_cfg.ns_per_insn * hil_board_cfg.mcu_clock_hz;
    return (uint32_t)((num + den / 2u) / den);
}

static void board_init(void)
{
    UART_BAUDDIV = 16u;
    UART_CTRL = CTRL_TXEN | CTRL_RXEN | CTRL_RXINTEN;
    NVIC_ISER0 = 1u << 0; /* IRQ 0: UART0 RX */
    SYST_RVR = 0x00FFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = 0x5u; /* enable, core clock, no interrupt */
    hil_serial_init(&serial);
}

static void service_frame(const hil_core_frame_t *in)
{
    static uint8_t packet[HIL_SERIAL_MAX_PACKET];
    hil_core_frame_t out;
    hil_core_rx(in->id, in->data, in->len, in->fd);
    while (hil_core_tx(&out)) {
        uart_write(packet, hil_serial_encode(&serial, &out, packet));
    }
}

#define MBOX32(off) (*(volatile uint32_t *)(HIL_MBOX_BASE + (off)))
#define MBOX8(off) (*(volatile uint8_t *)(HIL_MBOX_BASE + (off)))

/* Arm semihosting (BKPT 0xAB; QEMU -semihosting-config enable=on,target=native): the call runs in QEMU's
 * vCPU thread, so a read of a host FIFO blocks the emulated CPU until the host writes -- no interrupt, no
 * QEMU I/O thread in between (QEMU's global lock stays taken meanwhile: its monitor and UART wait too). The
 * "memory" clobber makes the argument block written before the call. */
#define SH_SYS_OPEN 0x01u
#define SH_SYS_WRITE 0x05u
#define SH_SYS_READ 0x06u
#define SH_MODE_RB 1u
#define SH_MODE_WB 5u

static int32_t semihost(uint32_t op, const uint32_t *args)
{
    register uint32_t r0 __asm__("r0") = op;
    register const uint32_t *r1 __asm__("r1") = args;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return (int32_t)r0;
}

static int32_t sh_open(uint32_t path_off, uint32_t mode)
{
    const char *path = (const char *)(HIL_MBOX_BASE + path_off);
    uint32_t args[3];
    uint32_t n = 0u;
    while (n < HIL_MBOX_PATH_SIZE - 1u && path[n] != '\0') {
        ++n;
    }
    args[0] = (uint32_t)(uintptr_t)path;
    args[1] = mode;
    args[2] = n;
    return semihost(SH_SYS_OPEN, args);
}

/* one byte through a host FIFO (SYS_READ blocks until the host writes); 0 when it went through */
static int32_t sh_bell(uint32_t op, int32_t handle)
{
    static uint8_t bell;
    uint32_t args[3];
    args[0] = (uint32_t)handle;
    args[1] = (uint32_t)(uintptr_t)&bell;
    args[2] = 1u;
    return semihost(op, args); /* the bytes not transferred */
}

/* The fast transport: frames in the shared PSRAM, doorbells through two host FIFOs (paths in the PSRAM,
 * written by the host before boot). Waiting on a FIFO instead of spinning on the sequence word leaves the
 * host's cores to the host (two spinners on a busy machine stall each other for scheduler time slices). The
 * doorbell calls run outside the step markers: the instruction counts are those of the step alone. */
static void mailbox_loop(void)
{
    uint32_t seen = MBOX32(HIL_MBOX_T2H_SEQ); /* the last request answered: one written before boot is served */
    hil_core_frame_t in;
    hil_core_frame_t out;
    const int32_t h2t = sh_open(HIL_MBOX_H2T_PATH, SH_MODE_RB);
    const int32_t t2h = sh_open(HIL_MBOX_T2H_PATH, SH_MODE_WB);
    for (;;) {
        const uint32_t seq = MBOX32(HIL_MBOX_H2T_SEQ);
        uint32_t len;
        uint32_t pos = 0u;
        uint32_t w = 0u;
        uint32_t j;
        if (seq == seen) {
            /* the host writes the sequence word before it rings: a bell rung after this check is not lost
             * (an extra bell from a request already served only costs one more look) */
            if (h2t >= 0 && sh_bell(SH_SYS_READ, h2t) != 0) {
                /* end of file: the host closed the mailbox and is stopping QEMU; sleep (a vCPU in WFI
                 * leaves QEMU's main loop free to act on the signal) */
                for (;;) {
                    __asm__ volatile("wfi" ::: "memory");
                }
            }
            continue;
        }
        __asm__ volatile("dmb" ::: "memory");
        len = MBOX32(HIL_MBOX_H2T_LEN);
        if (len > HIL_MBOX_BUF_SIZE) {
            len = 0u;
        }
        while (pos + 6u <= len) {
            const uint32_t b = HIL_MBOX_H2T_BUF + pos;
            in.id = (uint32_t)MBOX8(b) | ((uint32_t)MBOX8(b + 1u) << 8) | ((uint32_t)MBOX8(b + 2u) << 16) |
                    ((uint32_t)MBOX8(b + 3u) << 24);
            in.fd = MBOX8(b + 4u);
            in.len = MBOX8(b + 5u);
            if (in.len > HIL_CORE_MAX_PAYLOAD || pos + 6u + in.len > len) {
                break;
            }
            for (j = 0u; j < in.len; ++j) {
                in.data[j] = MBOX8(b + 6u + j);
            }
            pos += 6u + in.len;
            hil_core_rx(in.id, in.data, in.len, in.fd);
            while (hil_core_tx(&out)) {
                const uint32_t o = HIL_MBOX_T2H_BUF + w;
                if (w + 6u + out.len > HIL_MBOX_BUF_SIZE) {
                    continue; /* reply buffer full: the frame is dropped (the host sees it missing) */
                }
                MBOX8(o) = (uint8_t)(out.id & 0xFFu);
                MBOX8(o + 1u) = (uint8_t)((out.id >> 8) & 0xFFu);
                MBOX8(o + 2u) = (uint8_t)((out.id >> 16) & 0xFFu);
                MBOX8(o + 3u) = (uint8_t)((out.id >> 24) & 0xFFu);
                MBOX8(o + 4u) = out.fd;
                MBOX8(o + 5u) = out.len;
                for (j = 0u; j < out.len; ++j) {
                    MBOX8(o + 6u + j) = out.data[j];
                }
                w += 6u + out.len;
            }
        }
        MBOX32(HIL_MBOX_T2H_LEN) = w;
        __asm__ volatile("dmb" ::: "memory");
        MBOX32(HIL_MBOX_T2H_SEQ) = seq; /* last, one 32-bit store: the reply is complete */
        seen = seq;
        if (t2h >= 0) {
            (void)sh_bell(SH_SYS_WRITE, t2h);
        }
    }
}

int main(void)
{
    hil_core_frame_t frame;
    board_init();
    hil_core_init();
    if (hil_board_cfg.magic == HIL_BOARD_CFG_MAGIC && hil_board_cfg.transport == HIL_BOARD_MAILBOX) {
        mailbox_loop();
    }
    for (;;) {
        __asm__ volatile("cpsid i" ::: "memory");
        uart_drain(); /* a byte held in the data register is never left behind */
        if (rx_head == rx_tail) {
            __asm__ volatile("wfi" ::: "memory"); /* a pending RX interrupt wakes it (taken after cpsie) */
        }
        __asm__ volatile("cpsie i" ::: "memory");
        while (rx_head != rx_tail) {
            const uint8_t b = rx_ring[rx_tail & (RX_RING - 1u)];
            rx_tail++;
            if (hil_serial_feed(&serial, b, &frame)) {
                service_frame(&frame);
            }
        }
    }
}
