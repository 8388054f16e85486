/* Host stalls: reading the target's process (loop_stall.h). Linux /proc; elsewhere every read fails and the loop
 * keeps its wall-clock timeout. */
#define _POSIX_C_SOURCE 200809L

#include <dirent.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "loop_stall.h"

/* The file's first bytes, NUL-terminated: their count, or -1. */
static int read_small(const char *path, char *buf, size_t cap)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    ssize_t n;
    if (fd < 0) {
        return -1;
    }
    n = read(fd, buf, cap - 1u);
    (void)close(fd);
    if (n <= 0) {
        return -1;
    }
    buf[n] = '\0';
    return (int)n;
}

/* The scheduler state letter of /proc/.../stat (after the command name's last ')'), '?' if unreadable. */
static char state_of(const char *path)
{
    char buf[512];
    const char *p;
    if (read_small(path, buf, sizeof buf) < 0) {
        return '?';
    }
    p = strrchr(buf, ')');
    if (p == NULL || p[1] != ' ') {
        return '?';
    }
    return p[2];
}

/* One thread into `s`: 0, or -1 when unreadable. */
static int add_thread(int32_t pid, long tid, nl_proc_sample_t *s)
{
    char path[96];
    char buf[128];
    char *end;
    long long exec_ns;
    long long delay_ns;
    char state;
    (void)snprintf(path, sizeof path, "/proc/%d/task/%ld/schedstat", (int)pid, tid);
    if (read_small(path, buf, sizeof buf) < 0) {
        return -1;
    }
    exec_ns = strtoll(buf, &end, 10);
    delay_ns = strtoll(end, NULL, 10);
    s->exec_ns += (int64_t)exec_ns;
    s->delay_ns += (int64_t)delay_ns;
    (void)snprintf(path, sizeof path, "/proc/%d/task/%ld/stat", (int)pid, tid);
    state = state_of(path);
    if (state == 'R') {
        s->runnable = 1;
    } else if (state == 'T' || state == 't') {
        s->stopped = 1;
    } else if (state == 'D') {
        s->disk_wait = 1;
    } else if (state == 'Z' || state == 'X' || state == '?') {
        return -1;
    }
    return 0;
}

int nl_proc_sample(int32_t pid, nl_proc_sample_t *s)
{
    char path[64];
    DIR *dir;
    const struct dirent *e;
    int threads = 0;
    int rc = 0;
    memset(s, 0, sizeof *s);
    if (pid <= 0) {
        return -1;
    }
    (void)snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
    dir = opendir(path);
    if (dir == NULL) {
        return -1;
    }
    while ((e = readdir(dir)) != NULL) {
        long tid;
        if (e->d_name[0] < '0' || e->d_name[0] > '9') {
            continue;
        }
        tid = strtol(e->d_name, NULL, 10);
        if (add_thread(pid, tid, s) == 0) {
            threads++;
        } else if (tid == (long)pid) {
            rc = -1; /* the process itself: gone or a zombie (a thread that just ended does not count) */
        }
    }
    (void)closedir(dir);
    return threads > 0 ? rc : -1;
}

int64_t nl_proc_available(const nl_proc_sample_t *a, const nl_proc_sample_t *b, int64_t wall_ns)
{
    const int64_t exec = b->exec_ns - a->exec_ns;
    return nl_guest_available(a, b, exec > 0 ? exec : 0, 1, wall_ns);
}

int64_t nl_guest_available(const nl_proc_sample_t *a, const nl_proc_sample_t *b, int64_t insns, int64_t ns_per_insn,
                           int64_t wall_ns)
{
    int64_t had = insns > 0 && ns_per_insn > 0 ? insns * ns_per_insn : 0;
    if (wall_ns > 0 && !a->runnable && !a->stopped && !a->disk_wait && !b->runnable && !b->stopped && !b->disk_wait) {
        const int64_t slept = wall_ns - (b->exec_ns - a->exec_ns) - (b->delay_ns - a->delay_ns);
        if (slept > 0) {
            had += slept;
        }
    }
    return had;
}

static int64_t guest_insns_now(const nl_own_time_t *o)
{
    return (int64_t)__atomic_load_n(o->guest_insns, __ATOMIC_RELAXED);
}

void nl_own_time_start(nl_own_time_t *o, int32_t pid, const uint64_t *guest_insns, int64_t ns_per_insn,
                       int64_t slice_ns, int64_t t0_ns)
{
    memset(o, 0, sizeof *o);
    o->pid = pid;
    o->slice_ns = slice_ns;
    o->guest_insns = guest_insns;
    o->ns_per_insn = ns_per_insn;
    o->t_prev = t0_ns;
    o->insns_prev = guest_insns != NULL ? guest_insns_now(o) : 0;
}

int nl_own_time_step(nl_own_time_t *o, int64_t t_ns)
{
    nl_proc_sample_t now;
    int64_t insns = 0;
    if (nl_proc_sample(o->pid, &now) != 0) {
        return -1;
    }
    if (o->guest_insns != NULL) {
        insns = guest_insns_now(o);
    }
    if (!o->watching) {
        const int64_t wall = t_ns - o->t_prev;
        o->had_ns += o->guest_insns != NULL ? (insns - o->insns_prev) * o->ns_per_insn
                                            : wall < o->slice_ns ? wall : o->slice_ns;
        o->watching = 1;
    } else if (o->guest_insns != NULL) {
        o->had_ns += nl_guest_available(&o->prev, &now, insns - o->insns_prev, o->ns_per_insn, t_ns - o->t_prev);
    } else {
        o->had_ns += nl_proc_available(&o->prev, &now, t_ns - o->t_prev);
    }
    o->prev = now;
    o->insns_prev = insns;
    o->t_prev = t_ns;
    return 0;
}
