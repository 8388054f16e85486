/* The native target's serve loop (target_serve.h): src/pmsm_hil/sim_target/process.py `serve` over the C target core (linked in,
 * or a SIL library's, through its function pointers). */
#define _POSIX_C_SOURCE 200809L

#include <signal.h>
#include <string.h>
#include <unistd.h>

#include "hil_target_core.h"
#include "loop_rt.h"
#include "target_serve.h"

#define CHECK_NS 50000000 /* parent, signal and idle checks at least this often [ns] */

static volatile sig_atomic_t g_stop;

static void on_signal(int signum)
{
    (void)signum;
    g_stop = 1;
}

int32_t nt_serve(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid)
{
    return nt_serve_core(l, idle_ns, parent_pid, hil_core_rx, hil_core_tx);
}

int32_t nt_serve_core(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid, nt_core_rx_fn rx, nt_core_tx_fn tx)
{
    return nt_serve_core_debug(l, idle_ns, parent_pid, rx, tx, NULL, NULL, NULL);
}

int32_t nt_serve_core_debug(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid, nt_core_rx_fn rx,
                            nt_core_tx_fn tx, const uint32_t *steps, const float *torque_ref, nl_sil_debug_t *debug)
{
    volatile nl_sil_debug_t *slot = debug;
    const volatile uint32_t *step_count = steps;
    const volatile float *tref = torque_ref;
    struct sigaction sa;
    struct sigaction old_term;
    struct sigaction old_int;
    hil_core_frame_t in;
    hil_core_frame_t out;
    int64_t last_rx = nl_now_ns();
    int64_t next_check = last_rx;
    int32_t end = 0;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    g_stop = 0;
    sigaction(SIGTERM, &sa, &old_term);
    sigaction(SIGINT, &sa, &old_int);
    while (end == 0) {
        int64_t now = nl_now_ns();
        const int got = l->recv(l->ctx, &in, now + CHECK_NS);
        if (got > 0) {
            rx(in.id, in.data, in.len, in.fd);
            if (slot != NULL && step_count != NULL && tref != NULL && *step_count != slot->steps) {
                slot->torque_ref = *tref; /* before the steps (the host reads a slot with steps > 0) */
                slot->steps = *step_count;
                __sync_synchronize(); /* both stores before the Command's send */
            }
            while (tx(&out)) {
                (void)l->send(l->ctx, &out);
            }
            now = nl_now_ns();
            last_rx = now;
        } else {
            now = nl_now_ns();
        }
        if (got < 0) {
            end = NT_END_CLOSED;
        } else if (g_stop) {
            end = NT_END_SIGNAL;
        } else if (now >= next_check) {
            next_check = now + CHECK_NS;
            if (parent_pid > 0 && getppid() != (pid_t)parent_pid) {
                end = NT_END_PARENT;
            } else if (idle_ns > 0 && now - last_rx > idle_ns) {
                end = NT_END_IDLE;
            }
        }
    }
    sigaction(SIGTERM, &old_term, NULL);
    sigaction(SIGINT, &old_int, NULL);
    return end;
}
