/* The floor of a lockstep exchange between two processes (link_floor.h). */
#define _GNU_SOURCE

#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "link_floor.h"
#include "loop_rt.h"

#define WARM_UP 200
#define PAYLOAD 32
#define RT_BINS 1024 /* round trips per 1 us bin for the median (the last open-ended) */

/* A UDP socket on 127.0.0.1, an ephemeral port; -1 on failure (errno set). */
static int loopback_socket(struct sockaddr_in *addr)
{
    socklen_t len = (socklen_t)sizeof *addr;
    const int s = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (s < 0) {
        return -1;
    }
    memset(addr, 0, sizeof *addr);
    addr->sin_family = AF_INET;
    addr->sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (bind(s, (const struct sockaddr *)addr, sizeof *addr) != 0 ||
        getsockname(s, (struct sockaddr *)addr, &len) != 0) {
        close(s);
        return -1;
    }
    return s;
}

/* Wait for one datagram as the native links do: spin, then block. 0 ok, -1 error. */
static int receive(int s, int64_t spin_ns)
{
    uint8_t buf[PAYLOAD];
    const int64_t spin_end = nl_now_ns() + spin_ns;
    struct pollfd p;
    do {
        if (recv(s, buf, sizeof buf, MSG_DONTWAIT) > 0) {
            return 0;
        }
    } while (nl_now_ns() < spin_end);
    p.fd = s;
    p.events = POLLIN;
    p.revents = 0;
    if (ppoll(&p, 1, NULL, NULL) < 0 && errno != EINTR) {
        return -1;
    }
    return recv(s, buf, sizeof buf, 0) > 0 ? 0 : -1;
}

/* Two connected loopback sockets; 0 ok, else errno (the sockets that opened are closed). */
static int32_t socket_pair(int *a, int *b)
{
    struct sockaddr_in a_addr;
    struct sockaddr_in b_addr;
    *a = loopback_socket(&a_addr);
    *b = *a < 0 ? -1 : loopback_socket(&b_addr);
    if (*a < 0 || *b < 0 || connect(*a, (const struct sockaddr *)&b_addr, sizeof b_addr) != 0 ||
        connect(*b, (const struct sockaddr *)&a_addr, sizeof a_addr) != 0) {
        const int32_t err = errno;
        if (*a >= 0) {
            close(*a);
        }
        if (*b >= 0) {
            close(*b);
        }
        return err != 0 ? err : EIO;
    }
    return 0;
}

/* Two connected loopback sockets and a forked child (*child 0 in the child); 0 ok, else errno (nothing open). */
static int32_t pair_and_fork(int *a, int *b, pid_t *child)
{
    int32_t err = socket_pair(a, b);
    if (err != 0) {
        return err;
    }
    *child = fork();
    if (*child < 0) {
        err = errno;
        close(*a);
        close(*b);
        return err;
    }
    return 0;
}

int32_t nl_udp_floor(int64_t n, int64_t spin_ns, nl_udp_floor_t *out)
{
    const uint8_t msg[PAYLOAD] = {0};
    int a;
    int b;
    int32_t err;
    int64_t i;
    int64_t total = 0;
    pid_t child;
    memset(out, 0, sizeof *out);
    err = pair_and_fork(&a, &b, &child);
    if (err != 0) {
        return err;
    }
    if (child == 0) { /* the echo: only system calls, then _exit (the parent may have other threads) */
        (void)prctl(PR_SET_PDEATHSIG, SIGKILL);
        for (i = 0; i < n + WARM_UP; ++i) {
            if (receive(b, spin_ns) != 0 || send(b, msg, sizeof msg, 0) < 0) {
                _exit(1);
            }
        }
        _exit(0);
    }
    for (i = 0; i < n + WARM_UP && err == 0; ++i) {
        const int64_t t0 = nl_now_ns();
        int64_t rt;
        if (send(a, msg, sizeof msg, 0) < 0 || receive(a, spin_ns) != 0) {
            err = errno != 0 ? errno : EIO;
            break;
        }
        rt = nl_now_ns() - t0;
        if (i >= WARM_UP) {
            total += rt;
            out->max_ns = rt > out->max_ns ? rt : out->max_ns;
            out->round_trips++;
        }
    }
    if (err != 0) {
        kill(child, SIGKILL);
    }
    while (waitpid(child, NULL, 0) < 0 && errno == EINTR) {
    }
    out->mean_ns = out->round_trips > 0 ? total / out->round_trips : 0;
    close(a);
    close(b);
    return err;
}

/* The round trip of 1 us bin `i` of `hist` holding the median of `count` round trips [ns]. */
static int64_t median_of(const int64_t *hist, int64_t count)
{
    int64_t seen = 0;
    int64_t i;
    for (i = 0; i < RT_BINS; ++i) {
        seen += hist[i];
        if (2 * seen >= count) {
            return i * 1000 + 500;
        }
    }
    return (RT_BINS - 1) * 1000;
}

int32_t nl_udp_paced_floor(int64_t n, int64_t period_ns, int32_t cpu, int32_t rt_priority, int64_t echo_spin_ns,
                           nl_udp_paced_floor_t *out)
{
    int64_t hist[RT_BINS];
    const uint8_t msg[PAYLOAD] = {0};
    uint8_t buf[PAYLOAD];
    nl_timing_cfg_t cfg;
    nl_result_t r;
    nl_rt_saved_t saved;
    int a;
    int b;
    int32_t err;
    int64_t i;
    int64_t start;
    pid_t child;
    memset(out, 0, sizeof *out);
    memset(hist, 0, sizeof hist);
    err = pair_and_fork(&a, &b, &child);
    if (err != 0) {
        return err;
    }
    if (child == 0) { /* the echo, as the run's target: same priority, any CPU; only system calls, then _exit */
        struct sched_param sp;
        (void)prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (rt_priority > 0) {
            memset(&sp, 0, sizeof sp);
            sp.sched_priority = rt_priority;
            (void)sched_setscheduler(0, SCHED_FIFO, &sp);
        }
        for (;;) {
            if (receive(b, echo_spin_ns) != 0 || send(b, msg, sizeof msg, 0) < 0) {
                _exit(0);
            }
        }
    }
    memset(&cfg, 0, sizeof cfg);
    memset(&r, 0, sizeof r);
    cfg.cpu = cpu;
    cfg.rt_priority = rt_priority;
    cfg.lock_memory = 1;
    nl_rt_setup(&cfg, &r, &saved);
    for (i = 0; i < WARM_UP && err == 0; ++i) { /* both ends warm */
        if (send(a, msg, sizeof msg, 0) < 0 || receive(a, 0) != 0) {
            err = errno != 0 ? errno : EIO;
        }
    }
    start = nl_now_ns() + period_ns;
    for (i = 0; i < n && err == 0; ++i) {
        const int64_t t0 = nl_wait_until(start, period_ns + 1);
        const int64_t deadline = start + period_ns;
        int64_t rt;
        int got = 0;
        if (send(a, msg, sizeof msg, 0) < 0) {
            err = errno;
            break;
        }
        while (!got && nl_now_ns() < deadline) {
            got = recv(a, buf, sizeof buf, MSG_DONTWAIT) > 0;
        }
        if (!got) {
            out->late++;
            if (receive(a, 0) != 0) {
                err = errno != 0 ? errno : EIO;
                break;
            }
        }
        rt = nl_now_ns() - t0;
        hist[rt / 1000 < RT_BINS ? rt / 1000 : RT_BINS - 1]++;
        out->max_ns = rt > out->max_ns ? rt : out->max_ns;
        out->periods++;
        start += period_ns;
        if (nl_now_ns() > start) { /* a late reply ran past the next start: go on from the period after it */
            start += ((nl_now_ns() - start) / period_ns + 1) * period_ns;
        }
    }
    nl_rt_restore(&saved);
    kill(child, SIGKILL);
    while (waitpid(child, NULL, 0) < 0 && errno == EINTR) {
    }
    out->median_ns = out->periods > 0 ? median_of(hist, out->periods) : 0;
    close(a);
    close(b);
    return err;
}
