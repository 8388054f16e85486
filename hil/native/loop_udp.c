/* The hiludp link in C (loop_udp.h): the same checks, in the same order, as UdpUnicastBus._pump. */
#define _GNU_SOURCE

#include <errno.h>
#include <netinet/in.h>
#include <string.h>
#include <sys/socket.h>

#include "hil_serial.h"
#include "loop_udp.h"

#define SESSION_SIZE 4
#define HEADER_SIZE 7
#define CRC_SIZE 2
#define DATA_MIN (SESSION_SIZE + HEADER_SIZE + CRC_SIZE)
#define LENGTH_AT (SESSION_SIZE + HEADER_SIZE - 1)
#define CONTROL_SIZE 14
#define MAX_DATAGRAM 2048
#define FLAG_FD 0x01u
#define FLAG_BRS 0x02u
#define ID_MASK 0x1FFFFFFFu
#define CTRL_VERSION 1u
#define CTRL_HELLO 1u
#define CTRL_ACK 2u

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void peer_address(const nl_udp_t *u, struct sockaddr_in *to)
{
    memset(to, 0, sizeof *to);
    to->sin_family = AF_INET;
    to->sin_addr.s_addr = u->peer_addr;
    to->sin_port = u->peer_port;
}

/* An ECONNREFUSED reports an earlier datagram refused by the peer's host (ICMP port unreachable, on a connected
 * socket): counted as a send error once a session is agreed, and this datagram is sent again once. */
static int send_to_peer(nl_udp_t *u, const uint8_t *buf, size_t n)
{
    struct sockaddr_in to;
    int refused = 0;
    peer_address(u, &to);
    while (sendto(u->fd, buf, n, 0, (const struct sockaddr *)&to, sizeof to) < 0) {
        if (errno == ECONNREFUSED && !refused) {
            refused = 1;
            if (u->session != 0u) {
                u->stats.send_errors++;
            }
        } else if (errno != EINTR) {
            u->stats.send_errors++;
            return -1;
        }
    }
    return 0;
}

/* connect() the socket to the peer on the HELLO the target adopts (Python's hiludp connects it already when it
 * opens; this keeps a socket opened otherwise safe too): the kernel then drops datagrams from every other address
 * before they reach the socket (junk cannot fill its receive buffer). Idempotent. */
static void connect_peer(nl_udp_t *u)
{
    struct sockaddr_in to;
    peer_address(u, &to);
    (void)connect(u->fd, (const struct sockaddr *)&to, sizeof to); /* failing, the address filter still applies */
}

int nl_udp_send(nl_udp_t *u, const hil_core_frame_t *f)
{
    uint8_t buf[DATA_MIN + HIL_CORE_MAX_PAYLOAD];
    uint16_t crc;
    const uint8_t flags = f->fd ? (uint8_t)(FLAG_FD | FLAG_BRS) : 0u;
    if (!nl_valid_length(f->len, f->fd)) {
        u->stats.send_errors++;
        return -1;
    }
    put_u32(buf, u->session);
    put_u32(buf + SESSION_SIZE, f->id & ID_MASK);
    buf[SESSION_SIZE + 4] = flags;
    buf[SESSION_SIZE + 5] = u->tx_seq;
    buf[SESSION_SIZE + 6] = f->len;
    memcpy(buf + SESSION_SIZE + HEADER_SIZE, f->data, f->len);
    crc = hil_serial_crc16(buf + SESSION_SIZE, (size_t)(HEADER_SIZE + f->len), 0xFFFFu);
    buf[SESSION_SIZE + HEADER_SIZE + f->len] = (uint8_t)(crc >> 8);
    buf[SESSION_SIZE + HEADER_SIZE + f->len + 1] = (uint8_t)(crc & 0xFFu);
    u->tx_seq = (uint8_t)(u->tx_seq + 1u);
    if (send_to_peer(u, buf, (size_t)(DATA_MIN + f->len)) != 0) {
        return -1;
    }
    u->stats.frames_tx++;
    return 0;
}

/* A control datagram (session 0): the target adopts a HELLO and acknowledges it. */
static void control(nl_udp_t *u, const uint8_t *d)
{
    const uint32_t sid = get_u32(d + 10);
    const uint8_t kind = d[8];
    if (memcmp(d + 4, "HILS", 4) != 0 || d[9] != CTRL_VERSION || (kind != CTRL_HELLO && kind != CTRL_ACK)
        || sid == 0u) {
        u->stats.framing_errors++;
    } else if (kind == CTRL_HELLO && u->target_role) {
        uint8_t ack[CONTROL_SIZE];
        if (u->session != sid) {
            u->rx_last = -1;
        }
        u->session = sid;
        connect_peer(u);
        put_u32(ack, 0u);
        memcpy(ack + 4, "HILS", 4);
        ack[8] = CTRL_ACK;
        ack[9] = CTRL_VERSION;
        put_u32(ack + 10, sid);
        (void)send_to_peer(u, ack, sizeof ack);
    } else {
        u->stats.session_dropped++;
    }
}

/* One datagram from the peer: 1 when it delivered a data frame into *f. */
static int datagram(nl_udp_t *u, const uint8_t *d, size_t n, hil_core_frame_t *f)
{
    const uint8_t *body = d + SESSION_SIZE;
    uint16_t crc;
    uint8_t len;
    if (n == CONTROL_SIZE && get_u32(d) == 0u) {
        control(u, d);
        return 0;
    }
    if (n < DATA_MIN || d[LENGTH_AT] != n - DATA_MIN) {
        u->stats.framing_errors++;
        return 0;
    }
    if (u->session == 0u || get_u32(d) != u->session) {
        u->stats.session_dropped++;
        return 0;
    }
    len = d[LENGTH_AT];
    crc = (uint16_t)(((uint16_t)d[n - 2] << 8) | d[n - 1]);
    if (hil_serial_crc16(body, (size_t)(HEADER_SIZE + len), 0xFFFFu) != crc) {
        u->stats.crc_errors++;
        return 0;
    }
    return nl_accept_framed(body, &u->rx_last, &u->stats, f);
}

int nl_udp_recv(nl_udp_t *u, hil_core_frame_t *f, int64_t deadline_ns)
{
    uint8_t buf[MAX_DATAGRAM];
    int64_t spin_end = -1;
    for (;;) {
        struct sockaddr_in from;
        socklen_t alen = sizeof from;
        const ssize_t n = recvfrom(u->fd, buf, sizeof buf, MSG_DONTWAIT, (struct sockaddr *)&from, &alen);
        if (n >= 0) {
            if (alen < (socklen_t)sizeof from || from.sin_family != AF_INET || from.sin_addr.s_addr != u->peer_addr
                || from.sin_port != u->peer_port) {
                u->stats.foreign_dropped++;
            } else if (datagram(u, buf, (size_t)n, f)) {
                return 1;
            }
            continue;
        }
        if (errno == EINTR) {
            continue;
        }
        if (errno == ECONNREFUSED) { /* an earlier datagram refused (ICMP port unreachable): as udp_bus.py */
            if (u->session != 0u) {
                u->stats.send_errors++;
            }
            continue;
        }
        if (errno != EAGAIN && errno != EWOULDBLOCK) { /* another ICMP error */
            u->stats.framing_errors++;
        }
        if (nl_wait_readable(u->fd, deadline_ns, &u->spin, &spin_end, &u->stats) == 0) {
            return 0; /* -1 (POLLERR: an ICMP error queued) is read and counted by the next recvfrom */
        }
    }
}

NL_LINK_DEFINE(nl_udp, nl_udp_t)
