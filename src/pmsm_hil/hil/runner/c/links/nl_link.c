/* What the links of the native loop share (nl_link.h). */
#define _GNU_SOURCE

#include <poll.h>
#include <string.h>
#include <time.h>

#include "loop_rt.h"
#include "hil_serial.h"
#include "nl_link.h"

int nl_seq_accept(int32_t *last, uint8_t seq, nl_link_stats_t *st)
{
    int d;
    if (*last < 0) {
        *last = seq;
        return 1;
    }
    d = (int)((uint8_t)(seq - (uint8_t)*last));
    if (d == 0) {
        st->duplicate++;
        return 0;
    }
    if (d < 128) {
        st->dropped += d - 1;
        *last = seq;
        return 1;
    }
    st->out_of_order++;
    return 1;
}

int nl_auth_open(hil_auth_t *a, const uint8_t *body, size_t n, nl_link_stats_t *st)
{
    const int verdict = hil_auth_open(a, body, n);
    if (verdict == HIL_AUTH_OK) {
        return 1;
    }
    if (verdict == HIL_AUTH_FAILED) {
        st->auth_failed++;
    } else {
        st->auth_replayed++;
    }
    return 0;
}

int nl_valid_length(uint8_t n, int fd)
{
    if (!fd) {
        return n <= 8u;
    }
    switch (n) { /* the CAN FD data lengths above 8 bytes */
    case 12u: case 16u: case 20u: case 24u: case 32u: case 48u: case 64u: return 1;
    default: return n <= 8u;
    }
}

#define FLAG_FD 0x01u
#define FLAG_EXTENDED 0x08u
#define FLAG_REMOTE 0x10u
#define HEADER_SIZE 7

int nl_accept_framed(const uint8_t *body, int32_t *rx_last, nl_link_stats_t *st, hil_core_frame_t *f)
{
    const uint8_t flags = body[4];
    const uint8_t len = body[6];
    if (!nl_valid_length(len, (flags & FLAG_FD) != 0u)) {
        st->framing_errors++;
        return 0;
    }
    if (!nl_seq_accept(rx_last, body[5], st)) {
        return 0;
    }
    st->frames_rx++;
    if (flags & (FLAG_EXTENDED | FLAG_REMOTE)) {
        st->ignored++;
        return 0;
    }
    hil_serial_unpack(body, f);
    memset(f->data + len, 0, (size_t)(HIL_CORE_MAX_PAYLOAD - len));
    return 1;
}

size_t nl_wire_pack(const nl_wire_frame_t *m, uint8_t seq, uint8_t *body)
{
    const int fd = (m->flags & NL_WIRE_FD) != 0u;
    const int remote = (m->flags & NL_WIRE_REMOTE) != 0u;
    const uint32_t id = m->id & ((m->flags & NL_WIRE_EXTENDED) ? 0x1FFFFFFFu : 0x7FFu);
    if ((m->flags & ~NL_WIRE_FLAGS) != 0u || !nl_valid_length(m->len, fd) || (remote && fd)
        || (!fd && (m->flags & (NL_WIRE_BRS | NL_WIRE_ESI)) != 0u) || id != m->id) {
        return 0u;
    }
    body[0] = (uint8_t)(id & 0xFFu);
    body[1] = (uint8_t)((id >> 8) & 0xFFu);
    body[2] = (uint8_t)((id >> 16) & 0xFFu);
    body[3] = (uint8_t)(id >> 24);
    body[4] = m->flags;
    body[5] = seq;
    body[6] = m->len;
    if (remote) {
        memset(body + NL_WIRE_HEADER, 0, m->len);
    } else {
        memcpy(body + NL_WIRE_HEADER, m->data, m->len);
    }
    return (size_t)(NL_WIRE_HEADER + m->len);
}

int nl_accept_wire(const uint8_t *body, int32_t *rx_last, nl_link_stats_t *st, nl_wire_frame_t *m)
{
    const uint8_t flags = body[4];
    const uint8_t len = body[6];
    if (!nl_valid_length(len, (flags & NL_WIRE_FD) != 0u) || ((flags & NL_WIRE_REMOTE) && len > 8u)) {
        st->framing_errors++;
        return 0;
    }
    if (!nl_seq_accept(rx_last, body[5], st)) {
        return 0;
    }
    st->frames_rx++;
    m->id = ((uint32_t)body[0] | ((uint32_t)body[1] << 8) | ((uint32_t)body[2] << 16) | ((uint32_t)body[3] << 24))
            & 0x1FFFFFFFu;
    m->flags = (uint8_t)(flags & NL_WIRE_FLAGS);
    m->len = len;
    if (flags & NL_WIRE_REMOTE) {
        memset(m->data, 0, sizeof m->data);
    } else {
        memcpy(m->data, body + HEADER_SIZE, len);
        memset(m->data + len, 0, (size_t)(HIL_CORE_MAX_PAYLOAD - len));
    }
    return 1;
}

static int64_t thread_cpu_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + (int64_t)ts.tv_nsec;
}

/* The wait of the receive before this one (from its first wait to its last poll), to the back-off check when it
 * blocked at once, else to the window. */
static void account_previous(nl_spin_t *sp)
{
    const int64_t wait = sp->rx_last_ns - sp->rx_start_ns;
    if (sp->rx_start_ns == 0) {
        return;
    }
    if (sp->rx_backed_off) {
        sp->check_wait_ns += wait;
        sp->check_n++;
    } else {
        sp->window_wait_ns += wait;
    }
}

/* Backed off: every NL_SPIN_CHECK receives, does blocking still wait less than the spinning it replaced? On a
 * machine whose load went away (or a window that only looked contended) a blocked receive waits for a wake-up
 * of an idle CPU: far longer than a spin. 1: keep blocking. */
static int backoff_pays(nl_spin_t *sp)
{
    int pays = 1;
    if (sp->check_n >= NL_SPIN_CHECK) {
        pays = sp->check_wait_ns <= sp->spin_wait_ns * sp->check_n;
        sp->check_n = 0;
        sp->check_wait_ns = 0;
    }
    return pays;
}

/* A window is full: contended or not (nl_link.h), and the back-off that follows. */
static void close_window(nl_spin_t *sp, int64_t now)
{
    const int64_t wall = now - sp->window_wall_ns;
    const int64_t waiting = wall - (thread_cpu_ns() - sp->window_cpu_ns) - sp->window_blocked_ns;
    /* runnable but not running for over a quarter of the time, or most spins ran out before the frame came:
     * spinning keeps a core from the peer or from the work that would wake it */
    if (4 * waiting > wall || 2 * sp->window_spun_out > NL_SPIN_WINDOW) {
        if (++sp->contended >= 2) { /* the load stayed: each back-off that follows one is longer */
            sp->block_left = NL_SPIN_BACKOFF << sp->doublings;
            sp->doublings += sp->doublings < NL_SPIN_BACKOFF_DOUBLINGS;
            sp->spin_wait_ns = sp->window_wait_ns / (NL_SPIN_WINDOW - 1);
            sp->check_n = 0;
            sp->check_wait_ns = 0;
            sp->backoffs++;
            sp->contended = 0;
        }
    } else {
        sp->contended = 0;
        sp->doublings = 0;
    }
    sp->window_n = 0;
}

/* A receive that has to wait: close the window when it is full and choose how this receive waits; returns its
 * spin end (now: block at once). */
static int64_t spin_start(nl_spin_t *sp, int64_t now)
{
    account_previous(sp);
    sp->rx_start_ns = now;
    sp->rx_last_ns = now;
    sp->spinning = 0;
    sp->rx_backed_off = 0;
    if (sp->block_left > 0) {
        if (backoff_pays(sp)) {
            sp->block_left--;
            sp->rx_backed_off = 1;
            return now;
        }
        sp->block_left = 0; /* spin again, and start over with the shortest back-off */
        sp->doublings = 0;
        sp->early_ends++;
    }
    if (sp->window_n == 0) {
        sp->window_wall_ns = now;
        sp->window_cpu_ns = thread_cpu_ns();
        sp->window_blocked_ns = 0;
        sp->window_wait_ns = 0;
        sp->window_spun_out = 0;
    }
    if (++sp->window_n >= NL_SPIN_WINDOW) {
        close_window(sp, now);
        if (sp->block_left > 0) {
            sp->block_left--;
            sp->rx_backed_off = 1;
            return now;
        }
    }
    sp->spinning = sp->spin_ns > 0;
    return now + sp->spin_ns;
}

int nl_wait_readable(int32_t fd, int64_t deadline_ns, nl_spin_t *sp, int64_t *spin_end, nl_link_stats_t *st)
{
    const int64_t now = nl_now_ns();
    if (now >= deadline_ns) {
        return 0;
    }
    if (*spin_end < 0) {
        *spin_end = spin_start(sp, now);
    }
    sp->rx_last_ns = now;
    if (now >= *spin_end) {
        struct pollfd p;
        struct timespec ts;
        const int64_t left = deadline_ns - now;
        int64_t blocked_ns;
        int ready;
        p.fd = fd;
        p.events = POLLIN;
        p.revents = 0;
        ts.tv_sec = (time_t)(left / 1000000000);
        ts.tv_nsec = (long)(left % 1000000000);
        st->blocked++;
        ready = ppoll(&p, 1, &ts, NULL);
        blocked_ns = nl_now_ns() - now;
        sp->rx_last_ns = now + blocked_ns;
        sp->window_blocked_ns += blocked_ns;
        if (sp->spinning) { /* the first block of a receive whose spin ran out */
            sp->spinning = 0;
            sp->window_spun_out += blocked_ns < NL_SPIN_NEAR_MISS_NS; /* the frame came soon after */
        }
        if (ready > 0 && (p.revents & (POLLHUP | POLLERR | POLLNVAL))) {
            return -1;
        }
    }
    return 1;
}
