/*
 * STM32G474 board layer of the firmware API: the clock set-up (HSE or HSI16 -> PLL -> 170 MHz), the DWT cycle
 * counter as the execution clock of exec_time_ns, a USART2 console, and the frames: each frame FDCAN1 receives
 * goes to the portable target core inside FDCAN1's interrupt; what the core answers (the Command of a
 * Measurement, ConfigAck, HeartbeatTarget, FaultTarget) goes back on FDCAN1. The host's Measurement paces the
 * control steps, as on every other board: one step per Measurement, in the interrupt of its arrival. The main
 * loop sleeps (WFI) between interrupts.
 */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "hil_target_core.h"
#include "stm32g474_regs.h"
#include "stm32g474_ll.h"

uint32_t SystemCoreClock = HIL_BOARD_HSI_HZ; /* HSI16 after reset */

void SystemInit(void)
{
    SCB->VTOR = FLASH_BASE; /* the vector table at the start of flash */
}

/* HSE (or HSI16) -> PLL M, N 85, R 2 (a 4 MHz PLL input, VCO 340 MHz) -> 170 MHz (stm32g474_ll.h). */
static void clock_init(void)
{
#if defined(HIL_BOARD_HSI)
    g4_clock_init(RCC_PLLCFGR_PLLSRC_HSI, HIL_BOARD_HSI_HZ / 4000000u, 85u, 2u);
#else
    g4_clock_init(RCC_PLLCFGR_PLLSRC_HSE, HIL_BOARD_HSE_HZ / 4000000u, 85u, 2u);
#endif
    SystemCoreClock = HIL_BOARD_SYSCLK_HZ;
}

void hil_board_console_write(const char *s)
{
    g4_usart2_write(s);
}

/* The DWT cycle counter at HCLK: the execution clock of the step (exec_time_ns). */
uint32_t hil_board_clock(void)
{
    return DWT->CYCCNT;
}

uint32_t hil_board_exec_ns(uint32_t t0, uint32_t t1)
{
    const uint64_t cycles = (uint64_t)(t1 - t0); /* wraps every 25 s at 170 MHz: one step is far shorter */
    return (uint32_t)((cycles * 1000000000u + SystemCoreClock / 2u) / SystemCoreClock);
}

void hil_board_frame_received(const hil_board_frame_t *in)
{
    hil_core_frame_t out;
    hil_board_frame_t tx;
    hil_core_rx(in->id, in->data, in->len, in->fd);
    while (hil_core_tx(&out)) {
        tx.id = out.id;
        tx.len = out.len;
        tx.fd = out.fd;
        memcpy(tx.data, out.data, out.len);
        (void)hil_board_can_send(&tx); /* a dropped frame is counted; the host sees it missing */
    }
}

int main(void)
{
    clock_init();
    CoreDebug->DEMCR |= CoreDebug_DEMCR_TRCENA_Msk;
    DWT->CYCCNT = 0u;
    DWT->CTRL |= DWT_CTRL_CYCCNTENA_Msk;
    g4_usart2_init(SystemCoreClock, HIL_BOARD_CONSOLE_BAUD);
    hil_core_init();
    if (hil_board_can_init() != 0) {
        hil_board_console_write("HIL-BOARD stm32g474: FDCAN1 did not start\n");
        for (;;) {
            __WFI();
        }
    }
    hil_board_console_write("HIL-BOARD stm32g474: target core on FDCAN1\n");
    for (;;) {
        __WFI(); /* every frame is served in FDCAN1_IT0_IRQHandler */
    }
}
