/* The floor of a lockstep exchange between two processes (link_floor.h). */
#define _GNU_SOURCE

#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
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

int32_t nl_udp_floor(int64_t n, int64_t spin_ns, nl_udp_floor_t *out)
{
    struct sockaddr_in a_addr;
    struct sockaddr_in b_addr;
    const uint8_t msg[PAYLOAD] = {0};
    int a;
    int b;
    int32_t err = 0;
    int64_t i;
    int64_t total = 0;
    pid_t child;
    memset(out, 0, sizeof *out);
    a = loopback_socket(&a_addr);
    b = a < 0 ? -1 : loopback_socket(&b_addr);
    if (a < 0 || b < 0 || connect(a, (const struct sockaddr *)&b_addr, sizeof b_addr) != 0 ||
        connect(b, (const struct sockaddr *)&a_addr, sizeof a_addr) != 0) {
        err = errno;
        goto done;
    }
    child = fork();
    if (child < 0) {
        err = errno;
        goto done;
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
done:
    if (a >= 0) {
        close(a);
    }
    if (b >= 0) {
        close(b);
    }
    return err;
}
