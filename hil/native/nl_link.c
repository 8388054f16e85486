/* What the links of the native loop share (nl_link.h). */
#define _GNU_SOURCE

#include <poll.h>
#include <string.h>
#include <time.h>

#include "loop_rt.h"
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

int nl_valid_length(uint8_t n, int fd)
{
    if (!fd) {
        return n <= 8u;
    }
    return n <= 8u || n == 12u || n == 16u || n == 20u || n == 24u || n == 32u || n == 48u || n == 64u;
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
    f->id = (uint32_t)body[0] | ((uint32_t)body[1] << 8) | ((uint32_t)body[2] << 16) | ((uint32_t)body[3] << 24);
    f->fd = (flags & FLAG_FD) ? 1u : 0u;
    f->len = len;
    memcpy(f->data, body + HEADER_SIZE, len);
    memset(f->data + len, 0, (size_t)(HIL_CORE_MAX_PAYLOAD - len));
    return 1;
}

static int64_t thread_cpu_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + (int64_t)ts.tv_nsec;
}

/* A receive that has to wait: close the window when it is full and choose how this receive waits; returns its
 * spin end (now: block at once). */
static int64_t spin_start(nl_spin_t *sp, int64_t now)
{
    sp->spinning = 0;
    if (sp->block_left > 0) {
        sp->block_left--;
        return now;
    }
    if (sp->window_n == 0) {
        sp->window_wall_ns = now;
        sp->window_cpu_ns = thread_cpu_ns();
        sp->window_blocked_ns = 0;
        sp->window_spun_out = 0;
    }
    if (++sp->window_n >= NL_SPIN_WINDOW) {
        const int64_t wall = now - sp->window_wall_ns;
        const int64_t waiting = wall - (thread_cpu_ns() - sp->window_cpu_ns) - sp->window_blocked_ns;
        /* runnable but not running for over a quarter of the time, or most spins ran out before the frame came:
         * spinning keeps a core from the peer or from the work that would wake it */
        if (4 * waiting > wall || 2 * sp->window_spun_out > NL_SPIN_WINDOW) {
            if (++sp->contended >= 2) {
                sp->block_left = NL_SPIN_BACKOFF;
                sp->backoffs++;
                sp->contended = 0;
            }
        } else {
            sp->contended = 0;
        }
        sp->window_n = 0;
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
    if (now >= *spin_end) {
        struct pollfd p;
        struct timespec ts;
        const int64_t left = deadline_ns - now;
        int ready;
        p.fd = fd;
        p.events = POLLIN;
        p.revents = 0;
        ts.tv_sec = (time_t)(left / 1000000000);
        ts.tv_nsec = (long)(left % 1000000000);
        st->blocked++;
        if (sp->spinning) { /* the first block of a receive whose spin ran out */
            sp->spinning = 0;
            sp->window_spun_out++;
        }
        ready = ppoll(&p, 1, &ts, NULL);
        sp->window_blocked_ns += nl_now_ns() - now;
        if (ready > 0 && (p.revents & (POLLHUP | POLLERR | POLLNVAL))) {
            return -1;
        }
    }
    return 1;
}
