/*
 * FDCAN1 (RM0440 section 44) carrying the project's DBC (src/pmsm_hil/protocol/hil.dbc, packed and unpacked by
 * the cantools-generated codec firmware_stub/generated/hil_protocol.c): Setpoint and ConfigParam in, ConfigAck,
 * HeartbeatTarget and FaultTarget out, as docs/protocol.md "Target behaviour" asks of a target.
 * The message RAM's layout, its RX FIFO 0 reads and the initialisation handshake: stm32g474_ll.h.
 */
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "device.h"
#include "fw.h"
#include "hil_protocol.h"
#include "stm32g474_ll.h"

#define INIT_TIMEOUT 100000u
#define NODE_TARGET 1u

static volatile uint32_t rx_count;
static uint32_t tx_dropped;
static uint8_t beats; /* HeartbeatTarget idle confirmations sent */

int can_init(void)
{
    uint32_t i;
    RCC->CCIPR &= ~RCC_CCIPR_FDCANSEL; /* kernel clock: HSE (00) */
    g4_fdcan1_pins(); /* PA11 RX, PA12 TX */

    FDCAN1->CCCR |= FDCAN_CCCR_INIT;
    if (g4_fdcan1_wait_init(FDCAN_CCCR_INIT, INIT_TIMEOUT) != 0) {
        return -1;
    }
    FDCAN1->CCCR |= FDCAN_CCCR_CCE;
    FDCAN1->CCCR |= FDCAN_CCCR_FDOE | FDCAN_CCCR_BRSE; /* classic and FD frames, bit-rate switching */
    /* nominal: 24 MHz / 3 = 8 MHz, 16 tq (1 + 13 + 2) = 500 kbit/s, SJW 2 */
    FDCAN1->NBTP = (1UL << FDCAN_NBTP_NSJW_Pos) | (2UL << FDCAN_NBTP_NBRP_Pos) | (12UL << FDCAN_NBTP_NTSEG1_Pos) |
                   (1UL << FDCAN_NBTP_NTSEG2_Pos);
    /* data: 24 MHz / 1, 12 tq (1 + 8 + 3) = 2 Mbit/s, SJW 3 */
    FDCAN1->DBTP = (0UL << FDCAN_DBTP_DBRP_Pos) | (7UL << FDCAN_DBTP_DTSEG1_Pos) | (2UL << FDCAN_DBTP_DTSEG2_Pos) |
                   (2UL << FDCAN_DBTP_DSJW_Pos);
    /* message RAM cleared, then two standard dual-ID filters into RX FIFO 0: Setpoint + ConfigParam,
     * HeartbeatHost; everything else (other standard ids, extended ids, remote frames) rejected */
    for (i = 0u; i < G4_MRAM_SIZE; i += 4u) {
        *g4_mram(i) = 0u;
    }
    *g4_mram(G4_MRAM_FLS + 0u) = (1UL << 30) | (1UL << 27) | ((uint32_t)HIL_PROTOCOL_SETPOINT_FRAME_ID << 16) |
                           (uint32_t)HIL_PROTOCOL_CONFIG_PARAM_FRAME_ID;
    *g4_mram(G4_MRAM_FLS + 4u) = (1UL << 30) | (1UL << 27) | ((uint32_t)HIL_PROTOCOL_HEARTBEAT_HOST_FRAME_ID << 16) |
                           (uint32_t)HIL_PROTOCOL_HEARTBEAT_HOST_FRAME_ID;
    FDCAN1->RXGFC = (2UL << FDCAN_RXGFC_LSS_Pos) | (2UL << FDCAN_RXGFC_ANFS_Pos) | (2UL << FDCAN_RXGFC_ANFE_Pos) |
                    FDCAN_RXGFC_RRFS | FDCAN_RXGFC_RRFE;
    FDCAN1->TXBC = 0u; /* TX FIFO mode */
    FDCAN1->IE = FDCAN_IE_RF0NE;
    FDCAN1->ILS = 0u; /* every group on interrupt line 0 */
    FDCAN1->ILE = FDCAN_ILE_EINT0;
    FDCAN1->CCCR &= ~FDCAN_CCCR_INIT;
    return g4_fdcan1_wait_init(0u, INIT_TIMEOUT);
}

uint32_t can_frames_received(void)
{
    return rx_count;
}

static void can_send(uint32_t id, const uint8_t *data, uint8_t len)
{
    uint32_t w[2] = {0u, 0u};
    uint32_t base;
    uint32_t i;
    uint32_t put;
    if ((FDCAN1->TXFQS & FDCAN_TXFQS_TFQF) != 0u) {
        tx_dropped++;
        return;
    }
    put = (FDCAN1->TXFQS & FDCAN_TXFQS_TFQPI) >> FDCAN_TXFQS_TFQPI_Pos;
    base = G4_MRAM_TXB + put * G4_MRAM_ELEMENT;
    *g4_mram(base) = (id & 0x7FFu) << 18; /* standard id, data frame */
    *g4_mram(base + 4u) = (uint32_t)len << 16; /* classic frame: DLC = length (<= 8) */
    memcpy(w, data, len);
    for (i = 0u; i < 2u; ++i) {
        *g4_mram(base + 8u + 4u * i) = w[i];
    }
    FDCAN1->TXBAR = 1UL << put;
}

void can_send_heartbeat(uint8_t state, uint8_t counter)
{
    struct hil_protocol_heartbeat_target_t hb;
    uint8_t buf[8];
    hb.node = NODE_TARGET;
    hb.state = state;
    hb.counter = counter;
    (void)hil_protocol_heartbeat_target_pack(buf, &hb, sizeof buf);
    can_send(HIL_PROTOCOL_HEARTBEAT_TARGET_FRAME_ID, buf, HIL_PROTOCOL_HEARTBEAT_TARGET_LENGTH);
}

static void send_fault(uint8_t code, uint32_t detail)
{
    struct hil_protocol_fault_target_t f;
    uint8_t buf[8];
    f.node = NODE_TARGET;
    f.code = code;
    f.detail = detail;
    (void)hil_protocol_fault_target_pack(buf, &f, sizeof buf);
    can_send(HIL_PROTOCOL_FAULT_TARGET_FRAME_ID, buf, HIL_PROTOCOL_FAULT_TARGET_LENGTH);
}

static void on_config(const uint8_t *data)
{
    struct hil_protocol_config_param_t cp;
    struct hil_protocol_config_ack_t ack;
    uint8_t buf[8];
    (void)hil_protocol_config_param_unpack(&cp, data, HIL_PROTOCOL_CONFIG_PARAM_LENGTH);
    ack.param_id = cp.param_id;
    ack.value = cp.value; /* echoed bit for bit */
    ack.status = fw_config(cp.param_id, cp.value) == 0 ? 0u : 5u;
    (void)hil_protocol_config_ack_pack(buf, &ack, sizeof buf);
    can_send(HIL_PROTOCOL_CONFIG_ACK_FRAME_ID, buf, HIL_PROTOCOL_CONFIG_ACK_LENGTH);
}

static void on_setpoint(const uint8_t *data)
{
    struct hil_protocol_setpoint_t sp;
    fw_setpoint_t s;
    int status;
    (void)hil_protocol_setpoint_unpack(&sp, data, HIL_PROTOCOL_SETPOINT_LENGTH);
    s.enable = sp.enable != 0u ? 1u : 0u;
    s.mode = sp.mode;
    s.reference = sp.reference;
    s.controller_id = sp.controller_id;
    status = fw_apply_setpoint(&s);
    if (status != 0) {
        send_fault((uint8_t)status, status == 6 ? sp.controller_id : sp.mode);
    }
    if (s.enable == 0u) { /* the confirmed safe stop */
        can_send_heartbeat(1u, beats);
        beats++;
    }
}

static void on_heartbeat(const uint8_t *data)
{
    struct hil_protocol_heartbeat_host_t hb;
    (void)hil_protocol_heartbeat_host_unpack(&hb, data, HIL_PROTOCOL_HEARTBEAT_HOST_LENGTH);
    if (hb.node != NODE_TARGET) {
        can_send_heartbeat(fw_running() ? 2u : 1u, hb.counter);
    }
}

void FDCAN1_IT0_IRQHandler(void)
{
    FDCAN1->IR = FDCAN_IR_RF0N; /* write 1 to clear, before draining: a frame arriving meanwhile sets it again */
    while ((FDCAN1->RXF0S & FDCAN_RXF0S_F0FL) != 0u) {
        g4_fdcan_rx_t e;
        g4_fdcan1_rx0_read(&e);
        FDCAN1->RXF0A = e.get;
        rx_count++;
        if ((e.r0 & (1UL << 30)) == 0u) { /* standard id */
            const uint32_t id = (e.r0 >> 18) & 0x7FFu;
            const uint8_t *data = (const uint8_t *)e.words;
            const uint8_t len = e.len;
            if (id == HIL_PROTOCOL_SETPOINT_FRAME_ID && len >= HIL_PROTOCOL_SETPOINT_LENGTH) {
                on_setpoint(data);
            } else if (id == HIL_PROTOCOL_CONFIG_PARAM_FRAME_ID && len >= HIL_PROTOCOL_CONFIG_PARAM_LENGTH) {
                on_config(data);
            } else if (id == HIL_PROTOCOL_HEARTBEAT_HOST_FRAME_ID && len >= HIL_PROTOCOL_HEARTBEAT_HOST_LENGTH) {
                on_heartbeat(data);
            }
        }
    }
}
