/* Serial framing (hil_serial.h): COBS + CRC-16, resynchronising at every 0x00 like the Python deframer. */
#include <string.h>

#include "hil_serial.h"

#define FLAG_FD 0x01u
#define FLAG_BRS 0x02u
#define FLAG_EXTENDED 0x08u
#define FLAG_REMOTE 0x10u

uint16_t hil_serial_crc16(const uint8_t *data, size_t n, uint16_t crc)
{
    size_t i;
    uint8_t b;
    for (i = 0u; i < n; ++i) {
        crc = (uint16_t)(crc ^ (uint16_t)((uint16_t)data[i] << 8));
        for (b = 0u; b < 8u; ++b) {
            crc = (crc & 0x8000u) ? (uint16_t)((uint16_t)(crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
        }
    }
    return crc;
}

size_t hil_serial_cobs_encode(const uint8_t *src, size_t n, uint8_t *dst)
{
    size_t out = 1u;
    size_t code_at = 0u;
    uint8_t code = 1u;
    size_t i;
    for (i = 0u; i < n; ++i) {
        if (src[i] == 0u) {
            dst[code_at] = code;
            code_at = out++;
            code = 1u;
        } else {
            dst[out++] = src[i];
            if (++code == 0xFFu) {
                dst[code_at] = code;
                code_at = out++;
                code = 1u;
            }
        }
    }
    dst[code_at] = code;
    return out;
}

int hil_serial_cobs_decode(const uint8_t *src, size_t n, uint8_t *dst)
{
    size_t i = 0u;
    size_t out = 0u;
    while (i < n) {
        const uint8_t code = src[i];
        size_t j;
        if (code == 0u || i + code > n) {
            return -1;
        }
        for (j = 1u; j < code; ++j) {
            if (src[i + j] == 0u) {
                return -1;
            }
            dst[out++] = src[i + j];
        }
        i += code;
        if (code != 0xFFu && i < n) {
            dst[out++] = 0u;
        }
    }
    return (int)out;
}

void hil_serial_init(hil_serial_t *s)
{
    memset(s, 0, sizeof *s);
}

size_t hil_serial_body(hil_serial_t *s, const hil_core_frame_t *f, uint8_t *raw)
{
    raw[0] = (uint8_t)(f->id & 0xFFu);
    raw[1] = (uint8_t)((f->id >> 8) & 0xFFu);
    raw[2] = (uint8_t)((f->id >> 16) & 0xFFu);
    raw[3] = (uint8_t)((f->id >> 24) & 0x1Fu);
    raw[4] = f->fd ? (uint8_t)(FLAG_FD | FLAG_BRS) : 0u;
    raw[5] = s->tx_seq++;
    raw[6] = f->len;
    memcpy(&raw[HIL_SERIAL_HEADER], f->data, f->len);
    return HIL_SERIAL_HEADER + (size_t)f->len;
}

size_t hil_serial_packet(uint8_t *raw, size_t n, uint8_t *out)
{
    const uint16_t crc = hil_serial_crc16(raw, n, 0xFFFFu);
    size_t m;
    raw[n] = (uint8_t)(crc >> 8);
    raw[n + 1u] = (uint8_t)(crc & 0xFFu);
    m = hil_serial_cobs_encode(raw, n + 2u, out);
    out[m] = 0u;
    return m + 1u;
}

size_t hil_serial_encode(hil_serial_t *s, const hil_core_frame_t *f, uint8_t *out)
{
    uint8_t raw[HIL_SERIAL_MAX_RAW];
    return hil_serial_packet(raw, hil_serial_body(s, f, raw), out);
}

static int valid_length(uint8_t len, int fd)
{
    if (!fd) {
        return len <= 8u;
    }
    return len <= 8u || len == 12u || len == 16u || len == 20u || len == 24u || len == 32u || len == 48u ||
           len == 64u;
}

static int packet(hil_serial_t *s, hil_core_frame_t *f)
{
    uint8_t raw[HIL_SERIAL_MAX_ENCODED];
    int n = hil_serial_cobs_decode(s->buf, s->n, raw);
    uint16_t crc;
    uint8_t flags;
    uint8_t len;
    if (n < (int)(HIL_SERIAL_HEADER + 2u)) {
        s->framing_errors++;
        return 0;
    }
    crc = (uint16_t)(((uint16_t)raw[n - 2] << 8) | raw[n - 1]);
    if (hil_serial_crc16(raw, (size_t)n - 2u, 0xFFFFu) != crc) {
        s->crc_errors++;
        return 0;
    }
    flags = raw[4];
    len = raw[6];
    if ((int)len != n - 2 - (int)HIL_SERIAL_HEADER || len > HIL_CORE_MAX_PAYLOAD ||
        !valid_length(len, flags & FLAG_FD)) {
        s->framing_errors++;
        return 0;
    }
    if (flags & (FLAG_EXTENDED | FLAG_REMOTE)) {
        s->ignored++;
        return 0;
    }
    hil_serial_unpack(raw, f);
    return 1;
}

void hil_serial_unpack(const uint8_t *body, hil_core_frame_t *f)
{
    const uint8_t len = body[6];
    f->id = (uint32_t)body[0] | ((uint32_t)body[1] << 8) | ((uint32_t)body[2] << 16) | ((uint32_t)body[3] << 24);
    f->fd = (body[4] & FLAG_FD) ? 1u : 0u;
    f->len = len;
    memcpy(f->data, body + HIL_SERIAL_HEADER, len);
}

int hil_serial_feed(hil_serial_t *s, uint8_t byte, hil_core_frame_t *f)
{
    int got = 0;
    if (byte == 0u) {
        if (s->discarding) {
            s->discarding = 0u;
        } else if (s->n > 0u) {
            got = packet(s, f);
        }
        s->n = 0u;
        return got;
    }
    if (s->discarding) {
        return 0;
    }
    if (s->n >= sizeof s->buf) {
        s->framing_errors++;
        s->n = 0u;
        s->discarding = 1u;
        return 0;
    }
    s->buf[s->n++] = byte;
    return 0;
}
