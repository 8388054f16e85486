/* The hiludp link (loop_udp.h): the loop's, the native target's and python-can's hiludp bus (wire_bus.py). */
#define _GNU_SOURCE

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <netinet/in.h>
#include <string.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <unistd.h>

#include "hil_serial.h"
#include "loop_rt.h"
#include "loop_udp.h"

#define SESSION_SIZE 4
#define HEADER_SIZE 7
#define CRC_SIZE 2
#define DATA_MIN (SESSION_SIZE + HEADER_SIZE + CRC_SIZE)
#define LENGTH_AT (SESSION_SIZE + HEADER_SIZE - 1)
#define CONTROL_SIZE 14
#define AUTH_CONTROL_SIZE (CONTROL_SIZE + 4 + HIL_AUTH_MAC_SIZE) /* + nonce u32 + MAC */
#define MAX_DATAGRAM 2048
#define FLAG_FD 0x01u
#define FLAG_BRS 0x02u
#define ID_MASK 0x1FFFFFFFu
#define CTRL_VERSION 1u
#define CTRL_HELLO 1u
#define CTRL_ACK 2u
#define CTRL_REJECT_KEY 3u   /* this end authenticates and the HELLO's MAC failed */
#define CTRL_REJECT_PLAIN 4u /* this end does not authenticate and the HELLO did */

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

/* Seals (when authenticating) and checksums the `body` bytes that follow the session id in `buf` and counts the
 * sequence number on; returns the datagram's length [bytes]. */
static size_t seal_datagram(nl_udp_t *u, uint8_t *buf, size_t body)
{
    uint16_t crc;
    if (u->auth.on) {
        hil_auth_seal(&u->auth, buf + SESSION_SIZE, body);
        body += HIL_AUTH_TRAILER;
    }
    crc = hil_serial_crc16(buf + SESSION_SIZE, body, 0xFFFFu);
    buf[SESSION_SIZE + body] = (uint8_t)(crc >> 8);
    buf[SESSION_SIZE + body + 1] = (uint8_t)(crc & 0xFFu);
    u->tx_seq = (uint8_t)(u->tx_seq + 1u);
    return SESSION_SIZE + body + CRC_SIZE;
}

int nl_udp_send(nl_udp_t *u, const hil_core_frame_t *f)
{
    uint8_t buf[DATA_MIN + HIL_CORE_MAX_PAYLOAD + HIL_AUTH_TRAILER];
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
    if (send_to_peer(u, buf, seal_datagram(u, buf, (size_t)(HEADER_SIZE + f->len))) != 0) {
        return -1;
    }
    u->stats.frames_tx++;
    return 0;
}

/* A control datagram of `kind` for session `sid` to the peer: a HELLO or ACK with the nonce and MAC when
 * authenticating, a REJECT never authenticated. */
static void send_control(nl_udp_t *u, uint8_t kind, uint32_t sid)
{
    uint8_t c[AUTH_CONTROL_SIZE];
    size_t n = CONTROL_SIZE;
    put_u32(c, 0u);
    memcpy(c + 4, "HILS", 4);
    c[8] = kind;
    c[9] = CTRL_VERSION;
    put_u32(c + 10, sid);
    if (u->auth.on && (kind == CTRL_HELLO || kind == CTRL_ACK)) {
        put_u32(c + CONTROL_SIZE, kind == CTRL_ACK ? u->nonce : 0u);
        hil_auth_control_mac(&u->auth, u->auth.tx_dir, c, CONTROL_SIZE + 4u, c + CONTROL_SIZE + 4);
        n = AUTH_CONTROL_SIZE;
    }
    (void)send_to_peer(u, c, n);
}

/* A fresh nonce for an adopted session (never 0). */
static uint32_t new_nonce(void)
{
    uint32_t v = 0u;
    while (v == 0u) {
        if (getrandom(&v, sizeof v, 0) != (ssize_t)sizeof v) {
            v = (uint32_t)nl_now_ns() ^ 0x9E3779B9u; /* no entropy source: still a value never reused in a run */
        }
    }
    return v;
}

/* The MAC of an authenticated control datagram from the peer matches. */
static int control_mac_ok(const nl_udp_t *u, const uint8_t *d)
{
    uint8_t mac[HIL_AUTH_MAC_SIZE];
    uint8_t diff = 0u;
    unsigned i;
    hil_auth_control_mac(&u->auth, u->auth.rx_dir, d, CONTROL_SIZE + 4u, mac);
    for (i = 0; i < HIL_AUTH_MAC_SIZE; i++) {
        diff |= (uint8_t)(mac[i] ^ d[CONTROL_SIZE + 4u + i]);
    }
    return diff == 0u;
}

/* The peer's answer (ACK or REJECT) to this end's proposal `sid`: an ACK (authenticated as this end is) agrees
 * the session, with the peer's nonce in the MAC context. */
static void answer(nl_udp_t *u, const uint8_t *d, size_t n, uint8_t kind, uint32_t sid)
{
    uint8_t ctx[8];
    if (kind == CTRL_REJECT_KEY || kind == CTRL_REJECT_PLAIN) {
        u->rejected = kind;
        return;
    }
    if ((n == AUTH_CONTROL_SIZE) != (u->auth.on != 0) || (u->auth.on && !control_mac_ok(u, d))) {
        u->stats.auth_failed++;
        return;
    }
    u->proposal = 0u;
    u->session = sid;
    if (u->auth.on) {
        u->nonce = get_u32(d + CONTROL_SIZE);
        put_u32(ctx, sid);
        put_u32(ctx + 4, u->nonce);
        hil_auth_set_context(&u->auth, ctx, sizeof ctx);
    }
    connect_peer(u);
}

/* A control datagram (session 0) of n bytes: the target adopts a HELLO (authenticated when this end is) and
 * acknowledges it; a HELLO refused for its authentication is answered with a REJECT. */
static void control(nl_udp_t *u, const uint8_t *d, size_t n)
{
    const uint32_t sid = get_u32(d + 10);
    const uint8_t kind = d[8];
    if (memcmp(d + 4, "HILS", 4) != 0 || d[9] != CTRL_VERSION || sid == 0u
        || (kind != CTRL_HELLO && kind != CTRL_ACK && kind != CTRL_REJECT_KEY && kind != CTRL_REJECT_PLAIN)) {
        u->stats.framing_errors++;
        return;
    }
    if (kind != CTRL_HELLO && u->proposal != 0u && sid == u->proposal) {
        answer(u, d, n, kind, sid);
        return;
    }
    if (kind == CTRL_HELLO && u->proposal > sid) { /* both ends proposed: the larger id wins, the peer adopts ours */
        u->next_hello_ns = 0;
        return;
    }
    if (kind == CTRL_REJECT_KEY || kind == CTRL_REJECT_PLAIN || !u->target_role || kind != CTRL_HELLO) {
        u->stats.session_dropped++;
        return;
    }
    if ((n == AUTH_CONTROL_SIZE) != (u->auth.on != 0)) { /* authenticated on one end only */
        u->stats.auth_failed++;
        send_control(u, u->auth.on ? (uint8_t)CTRL_REJECT_KEY : (uint8_t)CTRL_REJECT_PLAIN, sid);
        return;
    }
    if (u->auth.on && !control_mac_ok(u, d)) {
        u->stats.auth_failed++;
        send_control(u, CTRL_REJECT_KEY, sid);
        return;
    }
    if (u->session != sid) { /* a new session (a repeated HELLO keeps the nonce and freshness of this one) */
        uint8_t ctx[8];
        u->rx_last = -1;
        u->session = sid;
        if (u->auth.on) {
            u->nonce = new_nonce();
            put_u32(ctx, sid);
            put_u32(ctx + 4, u->nonce);
            hil_auth_set_context(&u->auth, ctx, sizeof ctx);
        }
    }
    u->proposal = 0u;
    connect_peer(u);
    send_control(u, CTRL_ACK, sid);
}

/* One datagram from the peer: 1 when it is a data datagram of the session whose checks passed (its body, header
 * + payload, at d + SESSION_SIZE); a control datagram is answered here. */
static int checked(nl_udp_t *u, const uint8_t *d, size_t n)
{
    const uint8_t *body = d + SESSION_SIZE;
    const size_t data_min = DATA_MIN + (u->auth.on ? HIL_AUTH_TRAILER : 0u);
    size_t body_n;
    uint16_t crc;
    if ((n == CONTROL_SIZE || n == AUTH_CONTROL_SIZE) && get_u32(d) == 0u) {
        control(u, d, n);
        return 0;
    }
    if (u->auth.on && n >= DATA_MIN && d[LENGTH_AT] == n - DATA_MIN) { /* a frame without the trailer */
        u->stats.auth_failed++;
        return 0;
    }
    if (n < data_min || d[LENGTH_AT] != n - data_min) {
        u->stats.framing_errors++;
        return 0;
    }
    if (u->session == 0u || get_u32(d) != u->session) {
        u->stats.session_dropped++;
        return 0;
    }
    body_n = n - SESSION_SIZE - CRC_SIZE;
    crc = (uint16_t)(((uint16_t)d[n - 2] << 8) | d[n - 1]);
    if (hil_serial_crc16(body, body_n, 0xFFFFu) != crc) {
        u->stats.crc_errors++;
        return 0;
    }
    return !u->auth.on || nl_auth_open(&u->auth, body, body_n, &u->stats);
}

/* One datagram from the peer: 1 when it delivered a data frame into *f. */
static int datagram(nl_udp_t *u, const uint8_t *d, size_t n, hil_core_frame_t *f)
{
    return checked(u, d, n) && nl_accept_framed(d + SESSION_SIZE, &u->rx_last, &u->stats, f);
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
        if (errno == ECONNREFUSED) { /* an earlier datagram refused (ICMP port unreachable) */
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

int32_t nl_udp_open(nl_udp_t *u, uint32_t bind_addr, uint16_t local_port, uint32_t peer_addr, uint16_t peer_port,
                    int32_t rcvbuf)
{
    struct sockaddr_in a;
    socklen_t n = sizeof u->rcvbuf;
    const int on = 1;
    int err;
    memset(u, 0, sizeof *u);
    u->rx_last = -1;
    u->target_role = 1;
    u->peer_addr = peer_addr;
    u->peer_port = peer_port;
    u->fd = socket(AF_INET, SOCK_DGRAM, 0);
    if (u->fd < 0) {
        return errno;
    }
    if (rcvbuf > 0 && setsockopt(u->fd, SOL_SOCKET, SO_RCVBUFFORCE, &rcvbuf, sizeof rcvbuf) != 0) {
        (void)setsockopt(u->fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf); /* capped at rmem_max */
    }
    (void)getsockopt(u->fd, SOL_SOCKET, SO_RCVBUF, &u->rcvbuf, &n);
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = bind_addr;
    a.sin_port = local_port;
    if (setsockopt(u->fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0
        || bind(u->fd, (const struct sockaddr *)&a, sizeof a) != 0
        || fcntl(u->fd, F_SETFL, fcntl(u->fd, F_GETFL) | O_NONBLOCK) != 0) {
        err = errno;
        nl_udp_close(u);
        return err;
    }
    connect_peer(u);
    return 0;
}

uint16_t nl_udp_local_port(const nl_udp_t *u)
{
    struct sockaddr_in a;
    socklen_t n = sizeof a;
    if (u->fd < 0 || getsockname(u->fd, (struct sockaddr *)&a, &n) != 0) {
        return 0u;
    }
    return ntohs(a.sin_port);
}

void nl_udp_close(nl_udp_t *u)
{
    if (u->fd >= 0) {
        (void)close(u->fd);
    }
    u->fd = -1;
}

void nl_udp_propose(nl_udp_t *u)
{
    u->rejected = 0;
    u->proposal = new_nonce();
    u->rx_last = -1;
    u->session = u->auth.on ? 0u : u->proposal; /* an authenticated session needs the peer's nonce (its ACK) */
    send_control(u, CTRL_HELLO, u->proposal);
    u->next_hello_ns = nl_now_ns() + NL_UDP_HELLO_NS;
}

/* Send a datagram, waiting until deadline_ns while the socket's send buffer is full: 0 sent, -1 a counted
 * error. An ECONNREFUSED (an earlier datagram refused by the peer's host) is counted once a session is agreed
 * and this datagram sent again once. */
static int send_waiting(nl_udp_t *u, const uint8_t *buf, size_t n, int64_t deadline_ns)
{
    int refused = 0;
    while (send(u->fd, buf, n, 0) < 0) {
        if (errno == ECONNREFUSED && !refused) {
            refused = 1;
            u->stats.send_errors += u->session != 0u;
        } else if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS) {
            struct pollfd p;
            const int64_t left = deadline_ns - nl_now_ns();
            if (left <= 0) {
                u->stats.send_errors++;
                return -1;
            }
            p.fd = u->fd;
            p.events = POLLOUT;
            p.revents = 0;
            (void)poll(&p, 1, (int)(left > 1000000000 ? 1000 : left / 1000000 + 1));
        } else if (errno != EINTR) {
            u->stats.send_errors++;
            return -1;
        }
    }
    return 0;
}

int nl_udp_send_wire(nl_udp_t *u, const nl_wire_frame_t *m, int64_t deadline_ns)
{
    uint8_t buf[DATA_MIN + HIL_CORE_MAX_PAYLOAD + HIL_AUTH_TRAILER];
    size_t body;
    if (u->session == 0u && u->proposal == 0u) {
        nl_udp_propose(u);
    }
    if (u->session == 0u) {
        return -3;
    }
    body = nl_wire_pack(m, u->tx_seq, buf + SESSION_SIZE);
    if (body == 0u) {
        u->stats.send_errors++;
        return -2;
    }
    put_u32(buf, u->session);
    if (send_waiting(u, buf, seal_datagram(u, buf, body), deadline_ns) != 0) {
        return -1;
    }
    u->stats.frames_tx++;
    return 0;
}

/* The kernel's count of datagrams dropped for the socket (SO_RXQ_OVFL) in a received datagram's control data. */
static void read_drops(nl_udp_t *u, struct msghdr *mh)
{
    struct cmsghdr *c;
    for (c = CMSG_FIRSTHDR(mh); c != NULL; c = CMSG_NXTHDR(mh, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
            uint32_t drops;
            memcpy(&drops, CMSG_DATA(c), sizeof drops);
            u->kernel_drops = (int64_t)drops;
        }
    }
}

int nl_udp_recv_wire(nl_udp_t *u, nl_wire_frame_t *m, int64_t deadline_ns)
{
    uint8_t buf[MAX_DATAGRAM];
    union {
        char bytes[CMSG_SPACE(sizeof(uint32_t))];
        struct cmsghdr align;
    } control_data;
    int64_t spin_end = -1;
    for (;;) {
        struct sockaddr_in from;
        struct iovec iov;
        struct msghdr mh;
        ssize_t n;
        int64_t now;
        int64_t until = deadline_ns;
        iov.iov_base = buf;
        iov.iov_len = sizeof buf;
        memset(&mh, 0, sizeof mh);
        mh.msg_name = &from;
        mh.msg_namelen = sizeof from;
        mh.msg_iov = &iov;
        mh.msg_iovlen = 1;
        mh.msg_control = control_data.bytes;
        mh.msg_controllen = sizeof control_data.bytes;
        n = recvmsg(u->fd, &mh, MSG_DONTWAIT);
        if (n >= 0) {
            read_drops(u, &mh);
            if (mh.msg_namelen < (socklen_t)sizeof from || from.sin_family != AF_INET
                || from.sin_addr.s_addr != u->peer_addr || from.sin_port != u->peer_port) {
                u->stats.foreign_dropped++;
            } else if (checked(u, buf, (size_t)n)
                       && nl_accept_wire(buf + SESSION_SIZE, &u->rx_last, &u->stats, m)) {
                return 1;
            }
            continue;
        }
        if (errno == EINTR) {
            continue;
        }
        if (errno == ECONNREFUSED) {
            u->stats.send_errors += u->session != 0u && u->proposal == 0u;
            continue;
        }
        if (errno == EBADF) { /* closed (a bus shut down from another thread): nothing will come */
            return 0;
        }
        if (errno != EAGAIN && errno != EWOULDBLOCK) {
            u->stats.framing_errors++;
        }
        now = nl_now_ns();
        if (u->proposal != 0u) { /* repeat the HELLO until the peer answers */
            if (now >= u->next_hello_ns) {
                send_control(u, CTRL_HELLO, u->proposal);
                u->next_hello_ns = now + NL_UDP_HELLO_NS;
            }
            until = u->next_hello_ns < deadline_ns ? u->next_hello_ns : deadline_ns;
        }
        if (nl_wait_readable(u->fd, until, &u->spin, &spin_end, &u->stats) == 0 && until >= deadline_ns) {
            return 0;
        }
    }
}
