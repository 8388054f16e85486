/* The SocketCAN link in C (loop_socketcan.h): python-can's frame layout and BusLink's counting. */
#define _GNU_SOURCE

#include <errno.h>
#include <linux/can.h>
#include <string.h>
#include <sys/socket.h>

#include "loop_rt.h"
#include "loop_socketcan.h"

#define SFF_MASK 0x7FFu

/* The smallest CAN FD length >= n (python-can: min(i for i in CAN_FD_DLC if i >= n)). */
static uint8_t fd_length(uint8_t n)
{
    static const uint8_t lengths[] = {12u, 16u, 20u, 24u, 32u, 48u, 64u};
    size_t i;
    if (n <= 8u) {
        return n;
    }
    for (i = 0u; i < sizeof lengths; ++i) {
        if (lengths[i] >= n) {
            return lengths[i];
        }
    }
    return 64u;
}

int nl_socketcan_send(nl_socketcan_t *s, const hil_core_frame_t *f)
{
    struct canfd_frame fr; /* a classic frame is its first CAN_MTU bytes (the layouts agree) */
    size_t mtu;
    ssize_t n;
    if (!nl_valid_length(f->len, f->fd) || (f->fd && !s->fd_frames)) {
        s->stats.send_errors++;
        return -1;
    }
    memset(&fr, 0, sizeof fr);
    fr.can_id = f->id & SFF_MASK;
    fr.len = f->len;
    fr.__res1 = f->len; /* python-can packs the DLC there (len8_dlc of a classic frame) */
    memcpy(fr.data, f->data, f->len);
    if (f->fd) {
        fr.flags = CANFD_FDF | CANFD_BRS;
        mtu = CANFD_MTU;
    } else {
        mtu = CAN_MTU;
    }
    do {
        n = send(s->fd, &fr, mtu, MSG_DONTWAIT);
    } while (n < 0 && errno == EINTR);
    if (n != (ssize_t)mtu) {
        s->stats.send_errors++;
        return -1;
    }
    s->stats.frames_tx++;
    return 0;
}

/* One received message (capture_message + BusLink.poll): 1 when it is an 11-bit data frame for *f. */
static int message(nl_socketcan_t *s, const struct canfd_frame *fr, size_t n, hil_core_frame_t *f)
{
    uint8_t len;
    if (n != CAN_MTU && n != CANFD_MTU) {
        s->stats.framing_errors++;
        return 0;
    }
    if (fr->can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) {
        s->stats.ignored++;
        return 0;
    }
    len = fd_length(fr->len);
    if (n == CAN_MTU && len > CAN_MAX_DLEN) {
        len = CAN_MAX_DLEN; /* python-can slices the 8 data bytes there are */
    }
    s->stats.frames_rx++;
    f->id = fr->can_id & SFF_MASK;
    f->fd = n == CANFD_MTU ? 1u : 0u;
    f->len = len;
    memcpy(f->data, fr->data, len);
    memset(f->data + len, 0, (size_t)(HIL_CORE_MAX_PAYLOAD - len));
    return 1;
}

#ifndef SO_RXQ_OVFL
#define SO_RXQ_OVFL 40
#endif

/* The kernel's drop count in a received message's ancillary data (SO_RXQ_OVFL), when there. */
static void note_drops(nl_socketcan_t *s, struct msghdr *mh)
{
    struct cmsghdr *c;
    for (c = CMSG_FIRSTHDR(mh); c != NULL; c = CMSG_NXTHDR(mh, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(uint32_t))) {
            uint32_t dropped;
            memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
            if (dropped > s->kernel_dropped) {
                s->kernel_dropped = dropped;
            }
        }
    }
}

int nl_socketcan_recv(nl_socketcan_t *s, hil_core_frame_t *f, int64_t deadline_ns)
{
    int64_t spin_end = -1;
    /* past the deadline (a drain, or a wait whose time is up): only NL_DRAIN_MAX frames in a row */
    const int late = deadline_ns <= 0 || nl_now_ns() >= deadline_ns;
    if (late && s->burst >= NL_DRAIN_MAX) {
        s->burst = 0;
        return 0;
    }
    if (!late) {
        s->burst = 0;
    }
    for (;;) {
        struct canfd_frame fr;
        /* room for the drop count and a timestamp (python-can turns SO_TIMESTAMPNS on for its socket) */
        union {
            char buf[CMSG_SPACE(sizeof(uint32_t)) + CMSG_SPACE(2 * sizeof(int64_t))];
            struct cmsghdr align;
        } control;
        struct iovec iov;
        struct msghdr mh;
        ssize_t n;
        iov.iov_base = &fr;
        iov.iov_len = sizeof fr;
        memset(&mh, 0, sizeof mh);
        mh.msg_iov = &iov;
        mh.msg_iovlen = 1;
        mh.msg_control = control.buf;
        mh.msg_controllen = sizeof control.buf;
        n = recvmsg(s->fd, &mh, MSG_DONTWAIT | MSG_TRUNC);
        if (n > 0) {
            note_drops(s, &mh);
            if (message(s, &fr, (size_t)n, f)) {
                s->burst += late;
                return 1;
            }
            continue;
        }
        if (n == 0) { /* a socketpair's peer closed (a CAN socket never reads 0 bytes) */
            return -1;
        }
        if (errno == EINTR) {
            continue;
        }
        if (errno != EAGAIN && errno != EWOULDBLOCK) { /* e.g. ENETDOWN: python-can raises, BusLink counts it */
            s->stats.framing_errors++;
        }
        if (nl_wait_readable(s->fd, deadline_ns, &s->spin, &spin_end, &s->stats) == 0) {
            s->burst = 0;
            return 0;
        }
    }
}

NL_LINK_DEFINE(nl_socketcan, nl_socketcan_t)
