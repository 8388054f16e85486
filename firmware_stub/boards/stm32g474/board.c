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

uint32_t SystemCoreClock = HIL_BOARD_HSI_HZ; /* HSI16 after reset */

void SystemInit(void)
{
    SCB->VTOR = FLASH_BASE; /* the vector table at the start of flash */
}

/* RM0440 sections 5.3.3, 6.1.5, 7.2: range 1 boost, 4 wait states, PLL to 170 MHz through AHB /2 for >= 1 us
 * (the boost-mode transition), every ready flag polled as ST's LL drivers do. */
static void clock_init(void)
{
    uint32_t i;
#if defined(HIL_BOARD_HSI)
    const uint32_t src = RCC_PLLCFGR_PLLSRC_HSI;
    const uint32_t pll_m = HIL_BOARD_HSI_HZ / 4000000u; /* 4 MHz PLL input */
#else
    const uint32_t src = RCC_PLLCFGR_PLLSRC_HSE;
    const uint32_t pll_m = HIL_BOARD_HSE_HZ / 4000000u;
#endif
    const uint32_t pll_n = 85u; /* VCO 340 MHz */
    const uint32_t pll_r = 2u;
    RCC->APB1ENR1 |= RCC_APB1ENR1_PWREN;
    (void)RCC->APB1ENR1;
    PWR->CR1 = (PWR->CR1 & ~PWR_CR1_VOS) | PWR_CR1_VOS_0;
    while ((PWR->SR2 & PWR_SR2_VOSF) != 0u) {
    }
    PWR->CR5 &= ~PWR_CR5_R1MODE;
    FLASH->ACR = (FLASH->ACR & ~FLASH_ACR_LATENCY) | FLASH_ACR_LATENCY_4WS | FLASH_ACR_PRFTEN | FLASH_ACR_ICEN |
                 FLASH_ACR_DCEN;
    while ((FLASH->ACR & FLASH_ACR_LATENCY) != FLASH_ACR_LATENCY_4WS) {
    }
#if !defined(HIL_BOARD_HSI)
    RCC->CR |= RCC_CR_HSEON;
    while ((RCC->CR & RCC_CR_HSERDY) == 0u) {
    }
#endif
    RCC->CR &= ~RCC_CR_PLLON;
    while ((RCC->CR & RCC_CR_PLLRDY) != 0u) {
    }
    RCC->PLLCFGR = src | ((pll_m - 1u) << RCC_PLLCFGR_PLLM_Pos) | (pll_n << RCC_PLLCFGR_PLLN_Pos) |
                   (((pll_r / 2u) - 1u) << RCC_PLLCFGR_PLLR_Pos) | RCC_PLLCFGR_PLLREN;
    RCC->CR |= RCC_CR_PLLON;
    while ((RCC->CR & RCC_CR_PLLRDY) == 0u) {
    }
    RCC->CFGR = (RCC->CFGR & ~(RCC_CFGR_HPRE | RCC_CFGR_PPRE1 | RCC_CFGR_PPRE2)) | RCC_CFGR_HPRE_DIV2;
    RCC->CFGR = (RCC->CFGR & ~RCC_CFGR_SW) | RCC_CFGR_SW_PLL;
    while ((RCC->CFGR & RCC_CFGR_SWS) != RCC_CFGR_SWS_PLL) {
    }
    for (i = 0u; i < 100u; ++i) { /* >= 1 us at 85 MHz */
        __asm__ volatile("nop");
    }
    RCC->CFGR = (RCC->CFGR & ~RCC_CFGR_HPRE) | RCC_CFGR_HPRE_DIV1;
    SystemCoreClock = HIL_BOARD_SYSCLK_HZ;
}

static void console_init(void)
{
    RCC->AHB2ENR |= RCC_AHB2ENR_GPIOAEN;
    RCC->APB1ENR1 |= RCC_APB1ENR1_USART2EN;
    (void)RCC->APB1ENR1;
    /* PA2 TX, PA3 RX: alternate function 7; kernel clock PCLK1 (CCIPR USART2SEL 00, its reset value) */
    GPIOA->MODER = (GPIOA->MODER & ~((3UL << 4) | (3UL << 6))) | (2UL << 4) | (2UL << 6);
    GPIOA->AFR[0] = (GPIOA->AFR[0] & ~((0xFUL << 8) | (0xFUL << 12))) | (7UL << 8) | (7UL << 12);
    USART2->CR1 = 0u;
    USART2->BRR = (SystemCoreClock + HIL_BOARD_CONSOLE_BAUD / 2u) / HIL_BOARD_CONSOLE_BAUD; /* oversampling 16 */
    USART2->CR1 = USART_CR1_TE | USART_CR1_RE | USART_CR1_UE;
}

void hil_board_console_write(const char *s)
{
    while (*s != '\0') {
        while ((USART2->ISR & USART_ISR_TXE_TXFNF) == 0u) {
        }
        USART2->TDR = (uint8_t)*s++;
    }
    while ((USART2->ISR & USART_ISR_TC) == 0u) {
    }
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
    console_init();
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
