/*
 * The firmware API's board layer for the STM32G474 (NUCLEO-G474RE, a CAN FD transceiver on PA11/PA12): the
 * portable target core (hil_target_core.c) on FDCAN1, the frames of docs/protocol.md in and out. What it assumes
 * of the hardware, in one place; override any value with `hil fw build --define NAME=VALUE`.
 */
#ifndef HIL_BOARD_STM32G474_H
#define HIL_BOARD_STM32G474_H

#include <stdint.h>

/* Clock source of the PLL: the HSE crystal (NUCLEO-G474RE: 24 MHz, X3) by default; `--define HIL_BOARD_HSI`
 * takes the internal 16 MHz oscillator instead (no crystal fitted). Either way SYSCLK = HCLK = PCLK1 = 170 MHz
 * (voltage range 1 boost, 4 flash wait states). */
#ifndef HIL_BOARD_HSE_HZ
#define HIL_BOARD_HSE_HZ 24000000u
#endif
#define HIL_BOARD_HSI_HZ 16000000u
#define HIL_BOARD_SYSCLK_HZ 170000000u

/* FDCAN1 (kernel clock PCLK1, 170 MHz): nominal 1 Mbit/s (prescaler 5: 34 time quanta, sample point 82 %), data
 * phase 5 Mbit/s (prescaler 1: 34 time quanta, sample point 79 %, transceiver delay compensation on).
 * `--define HIL_BOARD_CLASSIC_CAN` runs classic CAN at the nominal rate only (the `can` link profile: frames of at
 * most 8 bytes). */
#define HIL_BOARD_CAN_NOMINAL_BPS 1000000u
#define HIL_BOARD_CAN_DATA_BPS 5000000u

/* USART2 (PA2 TX / PA3 RX, the NUCLEO's ST-LINK virtual COM port): boot and fault lines, 8N1 */
#ifndef HIL_BOARD_CONSOLE_BAUD
#define HIL_BOARD_CONSOLE_BAUD 115200u
#endif

/* board.c */
void hil_board_console_write(const char *s);

/* fdcan.c: FDCAN1 for the target core */
typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t fd;
    uint8_t data[64];
} hil_board_frame_t;

/* Set up FDCAN1 and its pins, filters for the host's frames into RX FIFO 0, its interrupt; 0 when it is on the
 * bus, -1 when it did not leave or enter initialisation. */
int hil_board_can_init(void);
/* Queue one frame for transmission (waits for a free TX FIFO element); 0 sent, -1 dropped (TX FIFO stayed full). */
int hil_board_can_send(const hil_board_frame_t *f);
/* board.c: one received frame, called from the FDCAN1 interrupt */
void hil_board_frame_received(const hil_board_frame_t *f);
/* frames lost in a full RX FIFO 0, frames dropped at transmission */
uint32_t hil_board_can_rx_lost(void);
uint32_t hil_board_can_tx_dropped(void);

void FDCAN1_IT0_IRQHandler(void);

#endif
