/* The hilserial link in C (loop_serial.h): the checks of a packet and of the frame in it
 * in the same order. */
#define _GNU_SOURCE

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "loop_rt.h"
#include "loop_serial.h"

#define CRC_SIZE 2

/* Wait until `fd` takes more output: 1, or 0 once deadline_ns has passed. */
static int wait_writable(int32_t fd, int64_t deadline_ns)
{
    struct pollfd p;
    struct timespec ts;
    const int64_t left = deadline_ns - nl_now_ns();
    if (left <= 0) {
        return 0;
    }
    p.fd = fd;
    p.events = POLLOUT;
    p.revents = 0;
    ts.tv_sec = (time_t)(left / 1000000000);
    ts.tv_nsec = (long)(left % 1000000000);
    (void)ppoll(&p, 1, &ts, NULL);
    return 1;
}

/* An authenticated frame as a packet (hil_serial_encode with the trailer before the CRC); returns its length. */
static size_t encode_sealed(nl_serial_t *s, const hil_core_frame_t *f, uint8_t *out)
{
    uint8_t raw[HIL_SERIAL_MAX_RAW + HIL_AUTH_TRAILER];
    const size_t n = hil_serial_body(&s->framer, f, raw);
    hil_auth_seal(&s->auth, raw, n);
    return hil_serial_packet(raw, n + HIL_AUTH_TRAILER, out);
}

/* Write a packet of n bytes, waiting while the output buffer is full for at most write_timeout_ns: 0 written
 * (frames_tx counted), -1 a counted send error. */
static int write_packet(nl_serial_t *s, const uint8_t *packet, size_t n)
{
    size_t at = 0u;
    int64_t deadline = -1;
    while (at < n) {
        const ssize_t w = write(s->fd, packet + at, n - at);
        if (w > 0) {
            at += (size_t)w;
        } else if (w < 0 && errno == EINTR) {
            continue;
        } else if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
            s->stats.send_errors++;
            return -1;
        } else {
            if (deadline < 0) {
                deadline = nl_now_ns() + s->write_timeout_ns;
            }
            if (!wait_writable(s->fd, deadline)) {
                s->stats.send_errors++;
                return -1;
            }
        }
    }
    s->stats.frames_tx++;
    return 0;
}

int nl_serial_send(nl_serial_t *s, const hil_core_frame_t *f)
{
    uint8_t packet[NL_SERIAL_MAX_ENCODED + 1];
    size_t n;
    if (!nl_valid_length(f->len, f->fd) || (f->fd && !s->fd_frames)) {
        s->stats.send_errors++;
        return -1;
    }
    n = s->auth.on ? encode_sealed(s, f, packet) : hil_serial_encode(&s->framer, f, packet);
    return write_packet(s, packet, n);
}

/* One packet between delimiters: 1 when its checks passed, its body
 * (header + payload) in raw. */
static int packet(nl_serial_t *s, uint8_t *raw)
{
    const int n = hil_serial_cobs_decode(s->pkt, (size_t)s->pkt_n, raw);
    const int trailer = s->auth.on ? (int)HIL_AUTH_TRAILER : 0;
    uint16_t crc;
    uint8_t len;
    if (n < (int)(HIL_SERIAL_HEADER + CRC_SIZE) + trailer) { /* malformed COBS too (-1) */
        s->stats.framing_errors++;
        return 0;
    }
    crc = (uint16_t)(((uint16_t)raw[n - 2] << 8) | raw[n - 1]);
    if (hil_serial_crc16(raw, (size_t)n - CRC_SIZE, 0xFFFFu) != crc) {
        s->stats.crc_errors++;
        return 0;
    }
    len = raw[6];
    if (trailer && (int)len == n - CRC_SIZE - (int)HIL_SERIAL_HEADER) { /* a frame without the trailer */
        s->stats.auth_failed++;
        return 0;
    }
    if ((int)len != n - CRC_SIZE - (int)HIL_SERIAL_HEADER - trailer || len > HIL_CORE_MAX_PAYLOAD) {
        s->stats.framing_errors++;
        return 0;
    }
    return !trailer || nl_auth_open(&s->auth, raw, (size_t)n - CRC_SIZE, &s->stats);
}

/* One received byte: 1 when it completed a packet whose checks passed, its body in raw. */
static int feed(nl_serial_t *s, uint8_t byte, uint8_t *raw)
{
    if (byte == 0u) {
        int got = 0;
        if (!s->discarding && s->pkt_n > 0) {
            got = packet(s, raw);
        }
        s->pkt_n = 0;
        s->discarding = 0;
        return got;
    }
    if (s->discarding) {
        return 0;
    }
    if (s->pkt_n >= (int32_t)HIL_SERIAL_MAX_ENCODED + (s->auth.on ? (int32_t)HIL_AUTH_TRAILER : 0)) {
        /* more than a packet can be without a delimiter */
        s->stats.framing_errors++;
        s->pkt_n = 0;
        s->discarding = 1;
        return 0;
    }
    s->pkt[s->pkt_n++] = byte;
    return 0;
}

/* The next packet whose checks passed into raw: 1; 0 when none came before deadline_ns; -1 the peer closed. */
static int next_packet(nl_serial_t *s, uint8_t *raw, int64_t deadline_ns)
{
    int64_t spin_end = -1;
    int hangup = 0;
    for (;;) {
        ssize_t n;
        int w;
        while (s->rx_at < s->rx_n) {
            if (feed(s, s->rx[s->rx_at++], raw)) {
                return 1;
            }
        }
        n = read(s->fd, s->rx, sizeof s->rx);
        if (n > 0) {
            s->rx_at = 0;
            s->rx_n = (int32_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if ((n < 0 && errno == EIO) || (n == 0 && hangup)) { /* the other end of the pty is closed */
            return -1;
        }
        /* 0: nothing (a raw tty with VMIN = 0) or end of file, EAGAIN: nothing (non-blocking) */
        w = nl_wait_readable(s->fd, deadline_ns, &s->spin, &spin_end, &s->stats);
        if (w == 0) {
            return 0;
        }
        hangup = w < 0;
    }
}

int nl_serial_recv(nl_serial_t *s, hil_core_frame_t *f, int64_t deadline_ns)
{
    uint8_t raw[NL_SERIAL_MAX_ENCODED];
    for (;;) {
        const int got = next_packet(s, raw, deadline_ns);
        if (got != 1 || nl_accept_framed(raw, &s->rx_last, &s->stats, f)) {
            return got;
        }
    }
}

NL_LINK_DEFINE(nl_serial, nl_serial_t)

int32_t nl_serial_attach(nl_serial_t *s, int32_t fd, int32_t fd_frames, int64_t write_timeout_ns)
{
    const int flags = fcntl(fd, F_GETFL);
    memset(s, 0, sizeof *s);
    s->fd = -1;
    s->rx_last = -1;
    hil_serial_init(&s->framer);
    if (flags < 0 || fcntl(fd, F_SETFL, flags | O_NONBLOCK) != 0) {
        return errno;
    }
    s->fd = fd;
    s->fd_frames = fd_frames;
    s->write_timeout_ns = write_timeout_ns;
    return 0;
}

void nl_serial_close(nl_serial_t *s)
{
    if (s->fd >= 0) {
        (void)close(s->fd);
    }
    s->fd = -1;
}

int nl_serial_send_wire(nl_serial_t *s, const nl_wire_frame_t *m)
{
    uint8_t raw[HIL_SERIAL_MAX_RAW + HIL_AUTH_TRAILER];
    uint8_t packet[NL_SERIAL_MAX_ENCODED + 1];
    size_t n;
    if ((m->flags & NL_WIRE_FD) && !s->fd_frames) {
        s->stats.send_errors++;
        return -2;
    }
    n = nl_wire_pack(m, s->framer.tx_seq, raw);
    if (n == 0u) {
        s->stats.send_errors++;
        return -2;
    }
    s->framer.tx_seq = (uint8_t)(s->framer.tx_seq + 1u);
    if (s->auth.on) {
        hil_auth_seal(&s->auth, raw, n);
        n += HIL_AUTH_TRAILER;
    }
    return write_packet(s, packet, hil_serial_packet(raw, n, packet));
}

int nl_serial_recv_wire(nl_serial_t *s, nl_wire_frame_t *m, int64_t deadline_ns)
{
    uint8_t raw[NL_SERIAL_MAX_ENCODED];
    for (;;) {
        const int got = next_packet(s, raw, deadline_ns);
        if (got != 1 || nl_accept_wire(raw, &s->rx_last, &s->stats, m)) {
            return got;
        }
    }
}
