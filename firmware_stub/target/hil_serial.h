/*
 * Serial framing of the HIL link in C (docs/protocol.md, "Serial framing"; the host's side:
 * src/pmsm_hil/hil/runner/c/links/loop_serial.c):
 * packet = COBS(header + payload + CRC-16/CCITT-FALSE big-endian) + 0x00, header = u32 LE id, u8 flags
 * (bit0 FD, bit1 BRS, bit3 extended, bit4 remote), u8 link sequence number, u8 payload length.
 */
#ifndef HIL_SERIAL_H
#define HIL_SERIAL_H

#include <stddef.h>
#include <stdint.h>

#include "hil_target_core.h"

#define HIL_SERIAL_HEADER 7u
#define HIL_SERIAL_MAX_RAW (HIL_SERIAL_HEADER + HIL_CORE_MAX_PAYLOAD + 2u)
#define HIL_SERIAL_MAX_ENCODED (HIL_SERIAL_MAX_RAW + HIL_SERIAL_MAX_RAW / 254u + 1u)
#define HIL_SERIAL_MAX_PACKET (HIL_SERIAL_MAX_ENCODED + 1u)

typedef struct {
    uint8_t buf[HIL_SERIAL_MAX_ENCODED];
    uint16_t n;
    uint8_t discarding;
    uint8_t tx_seq;
    uint32_t framing_errors;
    uint32_t crc_errors;
    uint32_t ignored;
} hil_serial_t;

/* CRC-16/CCITT-FALSE (poly 0x1021, init given, no reflection). */
uint16_t hil_serial_crc16(const uint8_t *data, size_t n, uint16_t crc);

/* COBS-encode n bytes of src into dst (no delimiter); returns the encoded length. */
size_t hil_serial_cobs_encode(const uint8_t *src, size_t n, uint8_t *dst);

/* COBS-decode n bytes into dst; returns the decoded length, or -1 when malformed. */
int hil_serial_cobs_decode(const uint8_t *src, size_t n, uint8_t *dst);

void hil_serial_init(hil_serial_t *s);

/* One frame as a packet (delimiter included) into out[HIL_SERIAL_MAX_PACKET]; returns its length. */
size_t hil_serial_encode(hil_serial_t *s, const hil_core_frame_t *f, uint8_t *out);

/* hil_serial_encode in two steps, for a sender adding bytes after the payload (an authentication trailer):
 * the header (taking the next link sequence number) and payload into raw (returns their length n), then the
 * packet of raw's first n bytes: CRC-16 appended at raw[n..n+1] (room needed), COBS and delimiter into out. */
size_t hil_serial_body(hil_serial_t *s, const hil_core_frame_t *f, uint8_t *raw);
size_t hil_serial_packet(uint8_t *raw, size_t n, uint8_t *out);

/* The frame of a checked header and payload (id little-endian at 0..3, flags at 4, sequence number at 5, length at
 * 6, the payload from HIL_SERIAL_HEADER) into *f: id, fd bit, length and payload. */
void hil_serial_unpack(const uint8_t *body, hil_core_frame_t *f);

/* Feed one received byte: 1 when it completed a valid data frame (written to *f), else 0. */
int hil_serial_feed(hil_serial_t *s, uint8_t byte, hil_core_frame_t *f);

#endif
