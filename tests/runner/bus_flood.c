/* bus_flood IFACE RATE KIND SEED — another node flooding a SocketCAN bus, counting what it put on it.
 *
 * RATE frames/s on an absolute schedule (frame k is due at t0 + k/RATE: after a late wake-up every frame due is
 * sent at once, so the rate holds on a starved CPU where `cangen -g 1`, which sleeps after each frame, loses every
 * overshoot); RATE 0: as fast as write() takes them. KIND `random`: random classic ids, lengths 0-8 and data;
 * `protocol`: hil.dbc's ids with random data of their lengths (CAN FD beyond 8 bytes). A write refused with
 * ENOBUFS is retried after a poll (cangen -p 10); only written frames count. Runs until SIGTERM or SIGINT, then
 * prints `sent N frames in T s` (T from the first frame's due time) on stdout. Built and run by
 * tests/runner/test_bus_flood_vcan.py inside .ci/vcan-vm. */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

static volatile sig_atomic_t running = 1;

static void on_signal(int sig)
{
    (void)sig;
    running = 0;
}

/* hil.dbc: the target's Commands (CmdA/B/C, CmdFd, CmdDutyFd), FaultTarget, ConfigAck, HeartbeatTarget, and the
 * host's MeasFd and Setpoint (another node posing as the host) */
static const struct {
    uint32_t id;
    uint8_t len;
} protocol_ids[] = {{0x110u, 8u}, {0x111u, 8u}, {0x112u, 8u}, {0x118u, 20u}, {0x119u, 24u},
                    {0x011u, 6u}, {0x211u, 6u}, {0x701u, 3u}, {0x108u, 16u}, {0x200u, 7u}};

static uint32_t rng_state;

static uint32_t rnd(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 17;
    rng_state ^= rng_state << 5;
    return rng_state;
}

static int64_t now_ns(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static size_t next_frame(struct canfd_frame *f, int protocol, uint64_t k)
{
    size_t n;
    size_t j;
    memset(f, 0, sizeof *f);
    if (protocol) {
        const size_t i = (size_t)(k % (sizeof protocol_ids / sizeof protocol_ids[0]));
        f->can_id = protocol_ids[i].id;
        f->len = protocol_ids[i].len;
    } else {
        f->can_id = rnd() & 0x7FFu;
        f->len = (uint8_t)(rnd() % 9u);
    }
    for (j = 0; j < f->len; ++j) {
        f->data[j] = (uint8_t)rnd();
    }
    n = f->len > 8u ? CANFD_MTU : CAN_MTU;
    return n;
}

int main(int argc, char **argv)
{
    struct sockaddr_can addr;
    struct canfd_frame f;
    const int on = 1;
    double rate;
    int protocol;
    int s;
    uint64_t sent = 0;
    int64_t t0;
    if (argc != 5) {
        fprintf(stderr, "usage: bus_flood IFACE RATE random|protocol SEED\n");
        return 2;
    }
    rate = strtod(argv[2], NULL);
    protocol = strcmp(argv[3], "protocol") == 0;
    rng_state = (uint32_t)strtoul(argv[4], NULL, 10) | 1u;
    s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (s < 0) {
        perror("bus_flood: socket");
        return 1;
    }
    (void)setsockopt(s, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on);
    (void)setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0); /* receives nothing */
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)if_nametoindex(argv[1]);
    if (addr.can_ifindex == 0 || bind(s, (struct sockaddr *)&addr, sizeof addr) < 0) {
        perror("bus_flood: bind");
        return 1;
    }
    (void)signal(SIGTERM, on_signal);
    (void)signal(SIGINT, on_signal);
    t0 = now_ns();
    while (running) {
        const size_t n = next_frame(&f, protocol, sent);
        if (rate > 0.0) {
            const int64_t due = t0 + (int64_t)((double)sent * 1e9 / rate);
            if (due > now_ns()) {
                struct timespec ts;
                ts.tv_sec = (time_t)(due / 1000000000);
                ts.tv_nsec = (long)(due % 1000000000);
                (void)clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
                continue; /* re-checks `running` and the time (a signal may have woken it) */
            }
        }
        if (write(s, &f, n) == (ssize_t)n) {
            sent++;
        } else if (errno == ENOBUFS || errno == EAGAIN) {
            struct pollfd p;
            p.fd = s;
            p.events = POLLOUT;
            (void)poll(&p, 1, 10);
        } else if (errno != EINTR) {
            perror("bus_flood: write");
            return 1;
        }
    }
    printf("sent %llu frames in %.3f s\n", (unsigned long long)sent, (double)(now_ns() - t0) * 1e-9);
    close(s);
    return 0;
}
