/*
 * FDCAN1 (RM0440 section 44) for the target core: the host's frames (Measurement parts, Setpoint, ConfigParam,
 * HeartbeatHost, FaultHost; ids from the DBC, generated/hil_protocol.h) pass the standard filters into RX FIFO 0,
 * everything else is rejected; its interrupt (line 0, IRQ 21) hands each frame to the board layer
 * (hil_board_frame_received: the target core serves it inside the interrupt).
 * The core's answers go out through the TX FIFO (3 elements), as FD frames with bit-rate switching when the core
 * answers a CAN FD frame.
 *
 * The message RAM's layout (RM0440 44.3.3), its RX FIFO 0 reads and the initialisation handshake: stm32g474_ll.h.
 */
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "hil_protocol.h"
#include "stm32g474_regs.h"
#include "stm32g474_ll.h"

#define INIT_TIMEOUT 100000u
#define TX_TIMEOUT 1000000u /* polls of a full TX FIFO before the frame is dropped (~10 ms at 170 MHz) */

/* standard filter element: SFT (00 range, 01 dual id), SFEC 001 (store in RX FIFO 0), SFID1, SFID2 */
#define SFT_RANGE 0u
#define SFT_DUAL 1u
#define SFEC_FIFO0 1u
#define STD_FILTER(sft, id1, id2) (((uint32_t)(sft) << 30) | ((uint32_t)SFEC_FIFO0 << 27) | \
                                   ((uint32_t)(id1) << 16) | (uint32_t)(id2))
#define N_FILTERS 4u

static uint32_t rx_lost;
static uint32_t tx_dropped;

int hil_board_can_init(void)
{
    uint32_t i;
    /* kernel clock PCLK1 (CCIPR FDCANSEL 10): 170 MHz */
    RCC->CCIPR = (RCC->CCIPR & ~RCC_CCIPR_FDCANSEL) | (2UL << RCC_CCIPR_FDCANSEL_Pos);
    g4_fdcan1_pins();

    FDCAN1->CCCR |= FDCAN_CCCR_INIT;
    if (g4_fdcan1_wait_init(FDCAN_CCCR_INIT, INIT_TIMEOUT) != 0) {
        return -1;
    }
    FDCAN1->CCCR |= FDCAN_CCCR_CCE;
#if !defined(HIL_BOARD_CLASSIC_CAN)
    FDCAN1->CCCR |= FDCAN_CCCR_FDOE | FDCAN_CCCR_BRSE; /* classic and FD frames, bit-rate switching */
#endif
    /* nominal: 170 MHz / 5 = 34 MHz, 34 tq (1 + 27 + 6) = 1 Mbit/s, SJW 6 */
    FDCAN1->NBTP = (5UL << FDCAN_NBTP_NSJW_Pos) | (4UL << FDCAN_NBTP_NBRP_Pos) | (26UL << FDCAN_NBTP_NTSEG1_Pos) |
                   (5UL << FDCAN_NBTP_NTSEG2_Pos);
    /* data: 170 MHz / 1, 34 tq (1 + 26 + 7) = 5 Mbit/s, SJW 7; transceiver delay compensation at the sample
     * point (27 kernel clocks) */
    FDCAN1->DBTP = (0UL << FDCAN_DBTP_DBRP_Pos) | (25UL << FDCAN_DBTP_DTSEG1_Pos) | (6UL << FDCAN_DBTP_DTSEG2_Pos) |
                   (6UL << FDCAN_DBTP_DSJW_Pos) | FDCAN_DBTP_TDC;
    FDCAN1->TDCR = 27UL << FDCAN_TDCR_TDCO_Pos;
    for (i = 0u; i < G4_MRAM_SIZE; i += 4u) {
        *g4_mram(i) = 0u;
    }
    *g4_mram(G4_MRAM_FLS + 0u) = STD_FILTER(SFT_RANGE, HIL_PROTOCOL_MEAS_A_FRAME_ID, HIL_PROTOCOL_MEAS6_B_FRAME_ID);
    *g4_mram(G4_MRAM_FLS + 4u) = STD_FILTER(SFT_DUAL, HIL_PROTOCOL_MEAS_FD_FRAME_ID, HIL_PROTOCOL_MEAS_FD6_FRAME_ID);
    *g4_mram(G4_MRAM_FLS + 8u) = STD_FILTER(SFT_DUAL, HIL_PROTOCOL_SETPOINT_FRAME_ID, HIL_PROTOCOL_CONFIG_PARAM_FRAME_ID);
    *g4_mram(G4_MRAM_FLS + 12u) =
        STD_FILTER(SFT_DUAL, HIL_PROTOCOL_HEARTBEAT_HOST_FRAME_ID, HIL_PROTOCOL_FAULT_HOST_FRAME_ID);
    /* N_FILTERS standard elements; non-matching standard and extended frames and remote frames rejected */
    FDCAN1->RXGFC = (N_FILTERS << FDCAN_RXGFC_LSS_Pos) | (2UL << FDCAN_RXGFC_ANFS_Pos) |
                    (2UL << FDCAN_RXGFC_ANFE_Pos) | FDCAN_RXGFC_RRFS | FDCAN_RXGFC_RRFE;
    FDCAN1->TXBC = 0u; /* TX FIFO mode */
    FDCAN1->IE = FDCAN_IE_RF0NE;
    FDCAN1->ILS = 0u; /* every group on interrupt line 0 */
    FDCAN1->ILE = FDCAN_ILE_EINT0;
    NVIC_SetPriority(FDCAN1_IT0_IRQn, 1u);
    NVIC_EnableIRQ(FDCAN1_IT0_IRQn);
    FDCAN1->CCCR &= ~FDCAN_CCCR_INIT;
    return g4_fdcan1_wait_init(0u, INIT_TIMEOUT);
}

void FDCAN1_IT0_IRQHandler(void)
{
    FDCAN1->IR = FDCAN_IR_RF0N; /* write 1 to clear, before draining: a frame arriving meanwhile sets it again */
    while ((FDCAN1->RXF0S & FDCAN_RXF0S_F0FL) != 0u) {
        g4_fdcan_rx_t e;
        hil_board_frame_t f;
        g4_fdcan1_rx0_read(&e);
        if ((FDCAN1->RXF0S & FDCAN_RXF0S_RF0L) != 0u) {
            rx_lost++; /* a frame found RX FIFO 0 full (blocking mode): the host sees its answer missing */
            FDCAN1->IR = FDCAN_IR_RF0L;
        }
        FDCAN1->RXF0A = e.get; /* the element is free again */
        f.id = (e.r0 >> 18) & 0x7FFu;        /* the filters pass standard ids only */
        f.fd = (uint8_t)((e.r1 >> 21) & 1u); /* FDF */
        f.len = e.len;
        memcpy(f.data, e.words, f.len);
        hil_board_frame_received(&f);
    }
}

int hil_board_can_send(const hil_board_frame_t *f)
{
    uint32_t words[16];
    uint32_t base;
    uint32_t put;
    uint32_t i;
    uint32_t n;
    uint32_t r1;
    for (n = 0u; (FDCAN1->TXFQS & FDCAN_TXFQS_TFQF) != 0u; ++n) {
        if (n >= TX_TIMEOUT) {
            tx_dropped++;
            return -1;
        }
    }
    put = (FDCAN1->TXFQS & FDCAN_TXFQS_TFQPI) >> FDCAN_TXFQS_TFQPI_Pos;
    base = G4_MRAM_TXB + put * G4_MRAM_ELEMENT;
    memset(words, 0, sizeof words);
    memcpy(words, f->data, f->len);
    r1 = g4_fdcan_bytes_dlc(f->len) << 16;
#if !defined(HIL_BOARD_CLASSIC_CAN)
    if (f->fd != 0u) {
        r1 |= (1UL << 21) | (1UL << 20); /* FDF, BRS */
    }
#endif
    *g4_mram(base) = (f->id & 0x7FFu) << 18; /* standard id, data frame */
    *g4_mram(base + 4u) = r1;
    for (i = 0u; i < ((uint32_t)f->len + 3u) / 4u; ++i) {
        *g4_mram(base + 8u + 4u * i) = words[i];
    }
    FDCAN1->TXBAR = 1UL << put;
    return 0;
}

uint32_t hil_board_can_rx_lost(void)
{
    return rx_lost;
}

uint32_t hil_board_can_tx_dropped(void)
{
    return tx_dropped;
}
