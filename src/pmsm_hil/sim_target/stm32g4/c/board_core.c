/* The virtual board's core in C: the NVIC's state (enable, pending, active, priorities, grouping, the level of each
 * line), SysTick, and the scheduler loop of one Board.run_until(end) (src/pmsm_hil/sim_target/stm32g4/board.py):
 * bring the models due up to now, take the pending exception that preempts (PRIMASK/BASEPRI, tail-chaining), find
 * the next event, then skip the time a WFI sleeps or run the core (uc_emu_start) up to it, and handle the slice's
 * stop (exception return, sleep, SVC). The same steps as the Python scheduler (Board._run_until_skipping, the
 * reference), compared record for record by tests/board/test_native_exc.py. What the loop cannot finish itself (a
 * fault, an unmapped access, a Python error) ends the call with a stop code; the Python side raises the error.
 *
 * Peripheral models plug in through periph_ops.h: a model in C is called directly; the models in Python are
 * called in batches (one call for every Python model due in a row, by a bit mask) through `py_advance`,
 * `py_next_event`, `py_quiet` and `py_next_each`. An event-driven model (Board.EVENT_DRIVEN) keeps its next event in
 * its slot and is advanced and asked again only when that cycle is reached or it was touched (an access, a core
 * clock change, a run-side input); a resting model stays resting across calls and reads (`rest_on_entry`). Unicorn's functions, the exception frames (c/exc_frame.c) and the instruction
 * counter (c/insn_count.c) are handed in as pointers. Built on first use (board_native.py). */
#include <stdint.h>
#include <string.h>

#include "periph_ops.h"

#define HIL_EXC_MAX 128
#define HIL_ACTIVE_MAX 64
#define HIL_MODELS_MAX 64
#define HIL_LOG_MAX 4096
#define HIL_IDLE_CACHE 64

#define NMI 2
#define HARDFAULT 3
#define SVCALL 11
#define SYSTICK 15
#define PRIO_MASK 0xF0
#define BASE_PRIORITY 0x100
#define MASKED_SLICE 64
#define ENTRY_CYCLES 12
#define RETURN_CYCLES 10
#define EXCP_SWI 2
#define EXCP_EXCEPTION_EXIT 8
#define UC_ERR_FETCH_PROT 14
#define UC_ERR_EXCEPTION 21
#define EXCP_PREFETCH_ABORT 3
#define UC_PROT_ALL 7

/* run's results */
enum {
    HIL_DONE = 0,         /* reached `end` */
    HIL_CONTINUE = 1,     /* (internal) the step is over, loop on */
    HIL_PY_ERROR = 2,     /* a Python callback or MMIO access raised: the exception is with the Python side */
    HIL_UC_ERROR = 3,     /* Unicorn returned `uc_error` */
    HIL_INTERRUPT = 4,    /* a CPU exception of the emulator other than SVC: `intno` */
    HIL_UNMAPPED = 5,     /* an access to unmapped memory: `access` (Unicorn's uc_mem_type), `address` */
    HIL_BAD_RETURN = 6,   /* an EXC_RETURN the core refuses (pc holds it) */
    HIL_LOG_FULL = 7      /* the ISR sample log is full: drain it and call again (resume) */
};

typedef struct {
    uint8_t enabled[HIL_EXC_MAX];
    uint8_t priority[HIL_EXC_MAX];
    uint8_t pending[HIL_EXC_MAX];
    uint8_t asserted[HIL_EXC_MAX];
    uint8_t has_assert[HIL_EXC_MAX];  /* assert_at is set: the cycle the line (or SysTick) asked */
    int64_t assert_at[HIL_EXC_MAX];
    int32_t active[HIL_ACTIVE_MAX];   /* in the order taken */
    int32_t n_active;
    int32_t prigroup;
    int32_t size;                     /* 16 + the part's interrupt lines */
    int32_t pad;
} hil_nvic_t;

typedef struct {
    uint32_t ctrl;
    uint32_t load;
    int64_t anchor;       /* cycle at which VAL was anchor_val */
    int64_t anchor_val;
    int64_t wraps;
    int32_t countflag;
    int32_t pad;
} hil_systick_t;

typedef struct {
    uint64_t count;
    uint64_t limit;
} hil_counter_head_t;

typedef int (*hil_reg_batch_fn)(void *uc, const int *regs, void **vals, int count);
typedef int (*hil_mem_read_fn)(void *uc, uint64_t address, void *bytes, uint64_t size);
typedef int (*hil_emu_start_fn)(void *uc, uint64_t begin, uint64_t until, uint64_t timeout, uint64_t count);
typedef int (*hil_emu_stop_fn)(void *uc);
typedef int (*hil_mem_protect_fn)(void *uc, uint64_t address, size_t size, uint32_t perms);
typedef int (*hil_exc_enter_fn)(const void *x, int in_thread, int fp, uint32_t ccr, uint32_t ipsr, uint32_t vector);
typedef int (*hil_exc_leave_fn)(const void *x, int use_psp, int fp);
typedef void (*hil_py_advance_fn)(uint64_t mask, int64_t now);
typedef int64_t (*hil_py_next_fn)(uint64_t active, uint64_t group, int64_t now, int64_t *group_out);
typedef uint64_t (*hil_py_quiet_fn)(uint64_t mask);
typedef void (*hil_py_next_each_fn)(uint64_t mask, int64_t now);

typedef struct {
    hil_periph_ops_t ops;  /* ops.advance / ops.next_event NULL: the model has none (a Python model: see `python`) */
    uint8_t python;        /* called through the batches, by its bit */
    uint8_t has_advance;
    uint8_t has_next;
    uint8_t in_group;      /* the TIM1/ADC event group */
    uint8_t may_rest;      /* has a quiet() */
    uint8_t resting;
    uint8_t woken;         /* a resting model accessed since the last step */
    uint8_t event_driven;  /* asked only when its next event (`due`) is reached or it was touched */
    uint8_t touched;       /* an event-driven model accessed (or changed from outside) since it was last asked */
    uint8_t pad[7];
    int64_t due;           /* an event-driven model's next event as it last answered (-1: none) */
} hil_model_t;

typedef struct {
    hil_nvic_t nvic;
    hil_systick_t systick;
    hil_counter_head_t *counter;
    /* Unicorn */
    void *uc;
    hil_emu_start_fn emu_start;
    hil_emu_stop_fn emu_stop;
    hil_reg_batch_fn reg_read_batch;
    hil_reg_batch_fn reg_write_batch;
    hil_mem_read_fn mem_read;
    int32_t reg_pc, reg_primask, reg_basepri, pad0;
    /* exception frames (c/exc_frame.c) */
    const void *exc;
    hil_exc_enter_fn exc_enter;
    hil_exc_leave_fn exc_leave;
    /* the SCB's state the loop needs (mirrored by the Python side after every SCS write) */
    uint32_t vtor, ccr;
    int32_t fp, sleep_on_exit;
    /* Python */
    hil_py_advance_fn py_advance;
    hil_py_next_fn py_next_event;
    hil_py_quiet_fn py_quiet;
    hil_py_next_each_fn py_next_each;  /* each Python event-driven model's next event into its slot's `due` */
    int32_t *py_error;     /* set by a Python callback or MMIO access that raised */
    /* the models, in the board's order */
    int32_t n_models;
    uint8_t group_touched;
    uint8_t sleeping;
    uint8_t rest_on_entry;  /* a resting model stays resting when run is called (woken only by a write or an input) */
    uint8_t pad1;
    hil_model_t models[HIL_MODELS_MAX];
    int64_t group_due;     /* -1: none */
    int64_t settled_at;    /* the models are up to this cycle (-1: not known) */
    int64_t sleep_cycles;
    int64_t handler_cycles;
    int64_t exc_entries;
    /* handlers being run: the exception and the cycle of its entry */
    int32_t entry_exc[HIL_ACTIVE_MAX];
    int64_t entry_at[HIL_ACTIVE_MAX];
    int32_t n_entry;
    /* what the Python side turns into IsrStats: kind 0 an entry (value: latency, -1 none), 1 a return (value: the
     * cycles spent in the handler) */
    int32_t n_log;
    int32_t log_exc[HIL_LOG_MAX];
    int32_t log_kind[HIL_LOG_MAX];
    int64_t log_value[HIL_LOG_MAX];
    /* the last stop */
    int32_t stop_kind;     /* 0 none, 1 interrupt, 2 unmapped, 3 exception return */
    int32_t intno;
    int32_t access;
    int32_t uc_error;
    uint64_t address;
    /* idle-loop shortcut: pc -> hit (1), miss (0) */
    uint32_t idle_pc[HIL_IDLE_CACHE];
    int8_t idle_hit[HIL_IDLE_CACHE];  /* -1: empty */
    /* the SRAMs mapped without execute permission until the core first fetches from them (Cpu.LAZY_RAM_EXEC) */
    hil_mem_protect_fn mem_protect;   /* uc_mem_protect */
    uint64_t ram_base[2];
    uint64_t ram_span[2];
    int32_t *ram_exec;                /* Cpu's flag: 1 once they are executable */
} hil_core_t;

/* --- NVIC ---------------------------------------------------------------------------------------------------- */

static int group_mask(const hil_core_t *c) { return (0xFF << (c->nvic.prigroup + 1)) & 0xFF; }

static int group_priority(const hil_core_t *c, int exc) {
    if (exc == NMI) {
        return -2;
    }
    if (exc == HARDFAULT) {
        return -1;
    }
    return c->nvic.priority[exc] & group_mask(c);
}

static int execution_priority(const hil_core_t *c, int primask, uint32_t basepri) {
    int prio = BASE_PRIORITY;
    for (int i = 0; i < c->nvic.n_active; ++i) {
        int g = group_priority(c, c->nvic.active[i]);
        if (g < prio) {
            prio = g;
        }
    }
    if (basepri & PRIO_MASK) {
        int b = (int)(basepri & PRIO_MASK) & group_mask(c);
        if (b < prio) {
            prio = b;
        }
    }
    if (primask && prio > 0) {
        prio = 0;
    }
    return prio;
}

/* The 8 flags of `flags` from index 8 * w, as one word (0: none set); past the NVIC's size read as clear. */
static uint64_t flag_word(const hil_core_t *c, const uint8_t *flags, int w) {
    uint64_t word;
    memcpy(&word, flags + 8 * w, sizeof word);
    int past = 8 * w + 8 - c->nvic.size;
    if (past > 0) {
        word = past >= 8 ? 0 : word & (~0ull >> (8 * past));  /* little-endian: the low bytes are the low indices */
    }
    return word;
}

static int flag_words(const hil_core_t *c) { return (c->nvic.size + 7) / 8; }

/* The pending, enabled exception taken first (lowest group priority, then sub-priority, then number); -1: none.
 * Only the words of `pending` with a flag set are looked at, in ascending order. */
int hil_core_best_pending(const hil_core_t *c) {
    int best = -1, bg = 0, bs = 0;
    for (int w = 0; w < flag_words(c); ++w) {
        if (!flag_word(c, c->nvic.pending, w)) {
            continue;
        }
        int top = 8 * w + 8 < c->nvic.size ? 8 * w + 8 : c->nvic.size;
        for (int exc = 8 * w; exc < top; ++exc) {
            if (!c->nvic.pending[exc] || !c->nvic.enabled[exc]) {
                continue;
            }
            int g = group_priority(c, exc);
            int s = exc > HARDFAULT ? c->nvic.priority[exc] : 0;
            if (best < 0 || g < bg || (g == bg && s < bs)) {
                best = exc, bg = g, bs = s;
            }
        }
    }
    return best;
}

static int preempting(const hil_core_t *c, int primask, uint32_t basepri) {
    int exc = hil_core_best_pending(c);
    if (exc < 0) {
        return -1;
    }
    return group_priority(c, exc) < execution_priority(c, primask, basepri) ? exc : -1;
}

static int any_pending(const hil_core_t *c) {
    for (int w = 0; w < flag_words(c); ++w) {
        if (flag_word(c, c->nvic.pending, w)) {
            return 1;
        }
    }
    return 0;
}

static int enabled_pending(const hil_core_t *c) {
    for (int w = 0; w < flag_words(c); ++w) {
        if (!flag_word(c, c->nvic.pending, w) || !flag_word(c, c->nvic.enabled, w)) {
            continue;
        }
        for (int exc = 8 * w; exc < 8 * w + 8 && exc < c->nvic.size; ++exc) {
            if (c->nvic.pending[exc] && c->nvic.enabled[exc]) {
                return 1;
            }
        }
    }
    return 0;
}

static int is_active(const hil_core_t *c, int exc) {
    for (int i = 0; i < c->nvic.n_active; ++i) {
        if (c->nvic.active[i] == exc) {
            return 1;
        }
    }
    return 0;
}

/* A model asserts interrupt line `irq` (level-sensitive): pending unless active; the core stops at its next block
 * when the line is enabled. The hil_irq_sink_t's assert_line (Python models reach it through Board.set_pending). */
void hil_core_assert_line(void *board, int irq) {
    hil_core_t *c = (hil_core_t *)board;
    int exc = 16 + irq;
    if (exc < 0 || exc >= c->nvic.size) {
        return;
    }
    if (!c->nvic.asserted[exc]) {
        c->nvic.assert_at[exc] = (int64_t)c->counter->count;
        c->nvic.has_assert[exc] = 1;
    }
    c->nvic.asserted[exc] = 1;
    if (!is_active(c, exc)) {
        c->nvic.pending[exc] = 1;
    }
    if (c->nvic.enabled[exc]) {
        c->counter->limit = c->counter->count;
    }
}

void hil_core_withdraw_line(void *board, int irq) {
    hil_core_t *c = (hil_core_t *)board;
    int exc = 16 + irq;
    if (exc < 0 || exc >= c->nvic.size) {
        return;
    }
    c->nvic.asserted[exc] = 0;
    c->nvic.pending[exc] = 0;
}

/* A model in C saw a register access (hil_irq_sink_t.touched): as Board._touch and Board._store do for the Python
 * models. */
void hil_core_touched(void *board, void *self, int write) {
    hil_core_t *c = (hil_core_t *)board;
    for (int i = 0; i < c->n_models; ++i) {
        hil_model_t *m = &c->models[i];
        if (m->python || m->ops.self != self) {
            continue;
        }
        if (m->in_group) {
            c->group_touched = 1;
        } else if (m->event_driven) {
            m->touched = 1;
        } else if (m->resting && (write || !c->rest_on_entry)) {
            m->woken = 1;
        }
        if (write && m->has_next) {
            int64_t at = m->ops.next_event(m->ops.self, (int64_t)c->counter->count);
            if (at >= 0 && (uint64_t)at < c->counter->limit) {
                c->counter->limit = c->counter->count;
            }
        }
        return;
    }
}

/* --- SysTick ------------------------------------------------------------------------------------------------- */

static int64_t systick_divider(const hil_systick_t *s) { return (s->ctrl & 4u) ? 1 : 8; }

int64_t hil_core_systick_next(const hil_core_t *c, int64_t now) {
    const hil_systick_t *s = &c->systick;
    if (!(s->ctrl & 1u) || (s->load == 0 && s->anchor_val == 0)) {
        return -1;
    }
    int64_t div = systick_divider(s);
    int64_t period = ((int64_t)s->load + 1) * div;
    int64_t first = s->anchor + (s->anchor_val + 1) * div;
    if (now < first) {
        return first;
    }
    return s->load ? first + ((now - first) / period + 1) * period : -1;
}

void hil_core_systick_advance(hil_core_t *c, int64_t now) {
    hil_systick_t *s = &c->systick;
    if (!(s->ctrl & 1u) || (s->load == 0 && s->anchor_val == 0)) {
        return;
    }
    int64_t div = systick_divider(s);
    int64_t first = s->anchor + (s->anchor_val + 1) * div;
    if (now < first) {
        return;
    }
    int64_t period = ((int64_t)s->load + 1) * div;
    int64_t wraps = 1 + (now - first) / period;
    s->anchor = first + (wraps - 1) * period;
    s->anchor_val = s->load;
    s->wraps += wraps;
    s->countflag = 1;
    if (s->ctrl & 2u) {
        if (!c->nvic.pending[SYSTICK]) {
            c->nvic.assert_at[SYSTICK] = s->anchor;
            c->nvic.has_assert[SYSTICK] = 1;
        }
        c->nvic.pending[SYSTICK] = 1;
    }
}

/* --- exceptions ---------------------------------------------------------------------------------------------- */

static void log_sample(hil_core_t *c, int exc, int kind, int64_t value) {
    if (c->n_log < HIL_LOG_MAX) {
        c->log_exc[c->n_log] = exc;
        c->log_kind[c->n_log] = kind;
        c->log_value[c->n_log] = value;
        ++c->n_log;
    }
}

static uint32_t read_reg(const hil_core_t *c, int id) {
    uint32_t value = 0;
    void *ptr = &value;
    c->reg_read_batch(c->uc, &id, &ptr, 1);
    return value;
}

static void read_masks(const hil_core_t *c, int *primask, uint32_t *basepri) {
    int ids[2] = {c->reg_primask, c->reg_basepri};
    uint32_t values[2] = {0, 0};
    void *ptrs[2] = {&values[0], &values[1]};
    c->reg_read_batch(c->uc, ids, ptrs, 2);
    *primask = (int)(values[0] & 1u);
    *basepri = values[1];
}

static int enter(hil_core_t *c, int exc) {
    hil_nvic_t *n = &c->nvic;
    int has = n->has_assert[exc];
    int64_t asserted = n->assert_at[exc];
    n->has_assert[exc] = 0;
    int ipsr = n->n_active ? n->active[n->n_active - 1] : 0;
    int err = c->exc_enter(c->exc, n->n_active == 0, c->fp, c->ccr, (uint32_t)ipsr, c->vtor + 4u * (uint32_t)exc);
    if (err) {
        c->uc_error = err;
        return HIL_UC_ERROR;
    }
    n->pending[exc] = 0;
    if (n->n_active < HIL_ACTIVE_MAX) {
        n->active[n->n_active++] = exc;
    }
    ++c->exc_entries;
    c->counter->count += ENTRY_CYCLES;
    int64_t now = (int64_t)c->counter->count;
    log_sample(c, exc, 0, has ? now - asserted : -1);
    if (c->n_entry < HIL_ACTIVE_MAX) {
        c->entry_exc[c->n_entry] = exc;
        c->entry_at[c->n_entry] = now;
        ++c->n_entry;
    }
    return HIL_CONTINUE;
}

static int take_pending(hil_core_t *c, int *taken) {
    int primask;
    uint32_t basepri;
    read_masks(c, &primask, &basepri);
    int exc = preempting(c, primask, basepri);
    *taken = 0;
    if (exc < 0) {
        return HIL_CONTINUE;
    }
    c->sleeping = 0;
    *taken = 1;
    return enter(c, exc);
}

static int idle_loop_at(hil_core_t *c, uint32_t pc) {
    uint32_t slot = (pc >> 1) % HIL_IDLE_CACHE;
    int hit;
    if (c->idle_hit[slot] >= 0 && c->idle_pc[slot] == pc) {
        hit = c->idle_hit[slot];
    } else {
        uint8_t code[4] = {0, 0, 0, 0};
        hit = pc >= 2 && c->mem_read(c->uc, pc - 2u, code, 4u) == 0 && code[0] == 0x30 && code[1] == 0xBF &&
              code[2] == 0xFD && code[3] == 0xE7;  /* wfi; b.n .-2 */
        c->idle_pc[slot] = pc;
        c->idle_hit[slot] = (int8_t)hit;
    }
    if (hit) { /* the branch and the WFI: two cycles; the core wakes at the WFI's successor */
        c->counter->count += 2;
        int id = c->reg_pc;
        void *ptr = &pc;
        c->reg_write_batch(c->uc, &id, &ptr, 1);
    }
    return hit;
}

static int leave(hil_core_t *c) {
    hil_nvic_t *n = &c->nvic;
    uint32_t exc_return = read_reg(c, c->reg_pc) | 1u;
    int valid = exc_return == 0xFFFFFFF1u || exc_return == 0xFFFFFFF9u || exc_return == 0xFFFFFFFDu ||
                exc_return == 0xFFFFFFE1u || exc_return == 0xFFFFFFE9u || exc_return == 0xFFFFFFEDu;
    if (!valid || n->n_active == 0 || ((exc_return & 8u) != 0) != (n->n_active == 1)) {
        return HIL_BAD_RETURN;
    }
    int exc = n->active[n->n_active - 1];
    int err = c->exc_leave(c->exc, (exc_return & 4u) != 0, !(exc_return & 0x10u));
    if (err) {
        c->uc_error = err;
        return HIL_UC_ERROR;
    }
    --n->n_active;
    if (n->asserted[exc]) {
        n->pending[exc] = 1;
    }
    c->counter->count += RETURN_CYCLES;
    int64_t now = (int64_t)c->counter->count;
    if (c->n_entry > 0) {
        --c->n_entry;
        int64_t spent = now - c->entry_at[c->n_entry];
        log_sample(c, c->entry_exc[c->n_entry], 1, spent);
        if (c->n_entry == 0) {
            c->handler_cycles += spent;
        }
    }
    if (n->pending[exc] && n->asserted[exc] && !n->has_assert[exc]) {
        n->assert_at[exc] = now;
        n->has_assert[exc] = 1;
    }
    if (n->n_active == 0) {
        int sleep = c->sleep_on_exit;
        if (!sleep) {
            uint32_t pc = read_reg(c, c->reg_pc);
            sleep = idle_loop_at(c, pc);
        }
        if (sleep) {
            c->sleeping = 1;
        }
    }
    return HIL_CONTINUE;
}

/* --- unicorn hooks (the slice's stop) ------------------------------------------------------------------------- */

void hil_core_on_interrupt(void *uc, uint32_t intno, void *user) {
    hil_core_t *c = (hil_core_t *)user;
    c->stop_kind = intno == EXCP_EXCEPTION_EXIT ? 3 : 1;
    c->intno = (int32_t)intno;
    c->emu_stop(uc);
}

int hil_core_on_unmapped(void *uc, int type, uint64_t address, int size, int64_t value, void *user) {
    hil_core_t *c = (hil_core_t *)user;
    (void)uc, (void)size, (void)value;
    if (type == 21 && address >= 0xFFFFFF00u) { /* UC_MEM_FETCH_UNMAPPED of an EXC_RETURN value */
        c->stop_kind = 3;
    } else {
        c->stop_kind = 2;
        c->access = type;
        c->address = address;
    }
    return 0;
}

/* --- the loop ------------------------------------------------------------------------------------------------ */

/* The core stopped with `err` before fetching at the pc: if it is the first fetch from the SRAMs, make them
 * executable (Cpu.grant_ram_exec's steps) and say so: the caller goes on from the pc. */
static int grant_ram_exec(hil_core_t *c, int err) {
    if (err != UC_ERR_FETCH_PROT || c->stop_kind != 0 || !c->ram_exec || *c->ram_exec) {
        return 0;
    }
    uint32_t pc = read_reg(c, c->reg_pc);
    int inside = 0;
    for (int i = 0; i < 2; ++i) {
        inside |= pc >= c->ram_base[i] && pc - c->ram_base[i] < c->ram_span[i];
    }
    if (!inside) {
        return 0;
    }
    for (int i = 0; i < 2; ++i) {
        if (c->mem_protect(c->uc, c->ram_base[i], (size_t)c->ram_span[i], UC_PROT_ALL) != 0) {
            return 0;
        }
    }
    *c->ram_exec = 1;
    return 1;
}

static int slice(hil_core_t *c, int64_t limit) {
    c->stop_kind = 0;
    c->counter->limit = (uint64_t)limit;
    uint64_t begun = c->counter->count;
    uint32_t pc = read_reg(c, c->reg_pc);
    int err = c->emu_start(c->uc, pc | 1u, 0xFFFFFFFFFFFFull, 0, 0);
    if (grant_ram_exec(c, err)) { /* nothing ran at the pc: the same slice goes on from there */
        err = c->emu_start(c->uc, read_reg(c, c->reg_pc) | 1u, 0xFFFFFFFFFFFFull, 0, 0);
    }
    if (err == UC_ERR_EXCEPTION && c->stop_kind == 0) { /* the virtual TLB refused a fetch (Cpu.VIRTUAL_TLB): the
                                                        * prefetch abort the CPU's own fill raises */
        c->stop_kind = 1;
        c->intno = EXCP_PREFETCH_ABORT;
    }
    if (err && c->stop_kind == 0) {
        c->uc_error = err;
        return HIL_UC_ERROR;
    }
    if (*c->py_error) {
        return HIL_PY_ERROR;
    }
    int kind = c->stop_kind;
    if (kind == 0) {
        uint32_t now_pc = read_reg(c, c->reg_pc);
        if (now_pc >= 0xFFFFFF00u) {
            kind = 3;
        } else if (c->counter->count > begun && now_pc >= 2) {
            uint16_t before = 0;
            if (c->mem_read(c->uc, now_pc - 2u, &before, 2u) != 0) {
                before = 0;
            }
            if (before == 0xBF30u || before == 0xBF20u) { /* WFI, WFE */
                c->sleeping = 1;
            }
            return HIL_CONTINUE;
        } else {
            return HIL_CONTINUE;
        }
    }
    if (kind == 3) {
        return leave(c);
    }
    if (kind == 1) {
        if (c->intno == EXCP_SWI) {
            c->nvic.pending[SVCALL] = 1;
            return HIL_CONTINUE;
        }
        return HIL_INTERRUPT;
    }
    return HIL_UNMAPPED;
}

static int sleep_or_run(hil_core_t *c, int64_t now, int64_t end, int64_t event) {
    if (c->sleeping) {
        int wakes = 0;
        if (any_pending(c)) {
            int primask;
            uint32_t basepri;
            read_masks(c, &primask, &basepri);
            wakes = preempting(c, 0, basepri) >= 0;
        }
        if (wakes) {
            c->sleeping = 0;
        } else {
            int64_t until = (event < 0 || end < event) ? end : event;
            c->sleep_cycles += until - now;
            c->counter->count = (uint64_t)until;
            return HIL_CONTINUE;
        }
    }
    int64_t limit = (event < 0 || end < event) ? end : event;
    if (enabled_pending(c) && now + MASKED_SLICE < limit) {
        limit = now + MASKED_SLICE;
    }
    return slice(c, limit > now + 1 ? limit : now + 1);
}

/* An event-driven model whose next event is reached or that was touched: advanced and asked again this step. */
static int model_due(const hil_model_t *m, int64_t now) {
    return m->touched || (m->due >= 0 && m->due <= now);
}

/* Advance every model due (group only when `hot`, resting ones only when woken, event-driven ones only when due),
 * in the board's order: a run of Python models in one batch call. */
static int advance_models(hil_core_t *c, int64_t now, int hot) {
    uint64_t mask = 0;
    for (int i = 0; i < c->n_models; ++i) {
        hil_model_t *m = &c->models[i];
        if (!m->has_advance || (m->in_group && !hot) || (m->resting && !m->woken) ||
            (m->event_driven && !model_due(m, now))) {
            continue;
        }
        if (m->python) {
            mask |= 1ull << i;
            continue;
        }
        if (mask) {
            c->py_advance(mask, now);
            mask = 0;
            if (*c->py_error) {
                return HIL_PY_ERROR;
            }
        }
        m->ops.advance(m->ops.self, now);
    }
    if (mask) {
        c->py_advance(mask, now);
        if (*c->py_error) {
            return HIL_PY_ERROR;
        }
    }
    return HIL_CONTINUE;
}

static void earlier(int64_t *best, int64_t at) {
    if (at >= 0 && (*best < 0 || at < *best)) {
        *best = at;
    }
}

/* The event-driven models' next events: those due or touched asked again (the Python ones in one batch call),
 * the others' as they last answered; the earliest into `best`. */
static int event_driven_due(hil_core_t *c, int64_t now, int64_t *best) {
    uint64_t mask = 0;
    for (int i = 0; i < c->n_models; ++i) {
        hil_model_t *m = &c->models[i];
        if (!m->event_driven || !model_due(m, now)) {
            continue;
        }
        m->touched = 0;
        if (m->python) {
            mask |= 1ull << i;
        } else {
            m->due = m->has_next ? m->ops.next_event(m->ops.self, now) : -1;
        }
    }
    if (mask) {
        c->py_next_each(mask, now);
        if (*c->py_error) {
            return HIL_PY_ERROR;
        }
    }
    for (int i = 0; i < c->n_models; ++i) {
        if (c->models[i].event_driven) {
            earlier(best, c->models[i].due);
        }
    }
    return HIL_CONTINUE;
}

/* The earliest next event of the active timed models (outside the group, not resting, not event-driven) and of
 * the event-driven ones into `active`, and when `group` the group's into `group_due`: the Python models of both in
 * one batch call. */
static int earliest(hil_core_t *c, int64_t now, int group, int64_t *active, int64_t *group_due) {
    int64_t best = -1, gbest = -1;
    uint64_t mask = 0, gmask = 0;
    int rc = event_driven_due(c, now, &best);
    if (rc != HIL_CONTINUE) {
        return rc;
    }
    for (int i = 0; i < c->n_models; ++i) {
        hil_model_t *m = &c->models[i];
        if (!m->has_next || m->event_driven || (m->in_group ? !group : m->resting)) {
            continue;
        }
        if (m->python) {
            if (m->in_group) {
                gmask |= 1ull << i;
            } else {
                mask |= 1ull << i;
            }
            continue;
        }
        earlier(m->in_group ? &gbest : &best, m->ops.next_event(m->ops.self, now));
    }
    if (mask || gmask) {
        int64_t gat = -1;
        int64_t at = c->py_next_event(mask, gmask, now, &gat);
        if (*c->py_error) {
            return HIL_PY_ERROR;
        }
        earlier(&best, at);
        earlier(&gbest, gat);
    }
    *active = best;
    if (group) {
        *group_due = gbest;
    }
    return HIL_CONTINUE;
}

/* One Board.run_until(end) (`fresh`: a new call, every model asked again; else the resumption of one that returned
 * to Python mid-way). Returns HIL_DONE or a stop code. */
int hil_core_run(hil_core_t *c, int64_t end, int fresh) {
    int64_t settled = -1;
    if (fresh) {
        c->group_touched = 1;
        for (int i = 0; i < c->n_models; ++i) {
            if (c->models[i].may_rest && !c->rest_on_entry) {
                c->models[i].woken = 1;
            }
        }
        settled = c->settled_at;
    }
    for (;;) {
        if (c->n_log > HIL_LOG_MAX - 8) {
            return HIL_LOG_FULL;
        }
        int64_t now = (int64_t)c->counter->count;
        int64_t group_due = c->group_due;
        int hot = c->group_touched || (group_due >= 0 && group_due <= now);
        int rc;
        if (now != settled) {
            hil_core_systick_advance(c, now);
            rc = advance_models(c, now, hot);
            if (rc != HIL_CONTINUE) {
                return rc;
            }
        }
        settled = -1;
        if (now >= end) {
            c->settled_at = now;
            return HIL_DONE;
        }
        if (any_pending(c)) {
            int taken;
            rc = take_pending(c, &taken);
            if (rc != HIL_CONTINUE) {
                return rc;
            }
            if (taken) {
                continue;
            }
        }
        uint64_t woken = 0;
        for (int i = 0; i < c->n_models; ++i) {
            if (c->models[i].woken) {
                woken |= 1ull << i;
            }
        }
        if (woken) {
            uint64_t quiet = c->py_quiet(woken);
            if (*c->py_error) {
                return HIL_PY_ERROR;
            }
            for (int i = 0; i < c->n_models; ++i) {
                if (woken >> i & 1u) {
                    c->models[i].resting = (uint8_t)(quiet >> i & 1u);
                    c->models[i].woken = 0;
                }
            }
        }
        /* the group asked when its event is due or it was accessed (next_event changes nothing: one batch) */
        int64_t event = hil_core_systick_next(c, now);
        int64_t at;
        int group = hot || c->group_touched;
        rc = earliest(c, now, group, &at, &group_due);
        if (rc != HIL_CONTINUE) {
            return rc;
        }
        earlier(&event, at);
        if (group) {
            c->group_touched = 0;
            c->group_due = group_due;
        }
        if (group_due >= 0 && (event < 0 || group_due < event)) {
            event = group_due;
        }
        rc = sleep_or_run(c, now, end, event);
        if (rc != HIL_CONTINUE) {
            return rc;
        }
    }
}

/* --- the NVIC's and SysTick's registers (0xE000E000 page) ---------------------------------------------------- */

typedef uint64_t (*hil_mmio_read_fn)(void *uc, uint64_t offset, unsigned size, void *user);
typedef void (*hil_mmio_write_fn)(void *uc, uint64_t offset, unsigned size, uint64_t value, void *user);

/* The System Control Space page as Unicorn MMIO callbacks: the NVIC's registers (ISER/ICER/ISPR/ICPR/IABR/IPR,
 * STIR) and SysTick's (CTRL/LOAD/VAL/CALIB) in C on the core's state, every other register through `fallback` /
 * `fallback_write` (the Python SystemControl, scs.py: the same steps, which name an unmodelled register). */
typedef struct {
    hil_core_t *core;
    hil_mmio_read_fn fallback;
    void *fallback_user;
    hil_mmio_write_fn fallback_write;
    void *fallback_write_user;
} hil_scs_t;

static int64_t floor_div(int64_t a, int64_t b) {
    int64_t q = a / b;
    return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

static int64_t systick_value(const hil_systick_t *s, int64_t now) {
    if (!(s->ctrl & 1u)) {
        return s->anchor_val;
    }
    int64_t ticks = floor_div(now - s->anchor, systick_divider(s));
    if (ticks <= s->anchor_val) {
        return s->anchor_val - ticks;
    }
    int64_t m = (int64_t)s->load + 1;
    int64_t r = (ticks - s->anchor_val - 1) % m;
    return (int64_t)s->load - (r < 0 ? r + m : r);
}

static int nvic_group_offset(uint64_t offset, uint64_t top) {
    return offset >= 0x100u && offset < top && (offset & 0x7Fu) < 0x20u;
}

uint64_t hil_core_scs_read(void *uc, uint64_t offset, unsigned size, void *user) {
    hil_scs_t *m = (hil_scs_t *)user;
    hil_core_t *c = m->core;
    const hil_nvic_t *n = &c->nvic;
    int irqs = n->size - 16;
    if (offset >= 0x400u && offset < 0x400u + (uint64_t)irqs) {
        uint64_t value = 0;
        int first = 16 + (int)(offset - 0x400u);
        for (unsigned i = 0; i < size; ++i) {
            if (first + (int)i < n->size) {
                value |= (uint64_t)n->priority[first + (int)i] << (8u * i);
            }
        }
        return value;
    }
    if (nvic_group_offset(offset, 0x320u)) {
        int group = (int)((offset - 0x100u) >> 7), word = (int)((offset & 0x7Fu) >> 2);
        uint64_t bits = 0;
        for (int bit = 0; bit < 32; ++bit) {
            int exc = 16 + 32 * word + bit;
            if (exc >= n->size) {
                break;
            }
            int on = group <= 1 ? n->enabled[exc] : group <= 3 ? n->pending[exc] : is_active(c, exc);
            bits |= (uint64_t)(on != 0) << bit;
        }
        return bits;
    }
    if (offset >= 0x10u && offset < 0x20u) {
        hil_systick_t *s = &c->systick;
        uint64_t reg = offset & ~3ull;
        if (reg == 0x10u) {
            uint64_t value = s->ctrl | (s->countflag ? 0x10000u : 0u);
            s->countflag = 0;
            return value;
        }
        if (reg == 0x14u) {
            return s->load;
        }
        if (reg == 0x18u) {
            return (uint64_t)systick_value(s, (int64_t)c->counter->count);
        }
        return 0x40000000u; /* CALIB: NOREF, no TENMS figure */
    }
    return m->fallback(uc, offset, size, m->fallback_user);
}

void hil_core_scs_write(void *uc, uint64_t offset, unsigned size, uint64_t value, void *user) {
    hil_scs_t *m = (hil_scs_t *)user;
    hil_core_t *c = m->core;
    hil_nvic_t *n = &c->nvic;
    int irqs = n->size - 16;
    int64_t now = (int64_t)c->counter->count;
    if (offset >= 0x400u && offset < 0x400u + (uint64_t)irqs) {
        for (unsigned i = 0; i < size; ++i) {
            int exc = 16 + (int)(offset - 0x400u) + (int)i;
            if (exc < n->size) {
                n->priority[exc] = (uint8_t)((value >> (8u * i)) & PRIO_MASK);
            }
        }
    } else if (nvic_group_offset(offset, 0x300u)) {
        int group = (int)((offset - 0x100u) >> 7), word = (int)((offset & 0x7Fu) >> 2);
        for (int bit = 0; bit < 32; ++bit) {
            if (!(value >> bit & 1u)) {
                continue;
            }
            int exc = 16 + 32 * word + bit;
            if (exc >= n->size) {
                break;
            }
            if (group == 0) {
                n->enabled[exc] = 1;
            } else if (group == 1) {
                n->enabled[exc] = 0;
            } else if (group == 2) {
                n->pending[exc] = 1;
            } else {
                n->pending[exc] = 0;
            }
        }
    } else if (offset >= 0x10u && offset < 0x20u) {
        hil_systick_t *s = &c->systick;
        uint64_t reg = offset & ~3ull;
        if (reg == 0x10u) {
            s->anchor_val = systick_value(s, now);
            s->ctrl = (uint32_t)(value & 7u);
            s->anchor = now;
        } else if (reg == 0x14u) {
            s->anchor_val = systick_value(s, now);
            s->anchor = now;
            s->load = (uint32_t)(value & 0xFFFFFFu);
        } else if (reg == 0x18u) { /* any write clears VAL and COUNTFLAG */
            s->anchor = now;
            s->anchor_val = 0;
            s->countflag = 0;
        }
    } else if (offset == 0xF00u) { /* STIR */
        int exc = 16 + (int)(value & 0x1FFu);
        if (exc < n->size) {
            n->pending[exc] = 1;
        }
    } else {
        m->fallback_write(uc, offset, size, value, m->fallback_write_user);
        return;
    }
    c->counter->limit = c->counter->count; /* the schedule is re-made after this block */
}

/* The size of hil_core_t (the Python mirror checks its own against it). */
int64_t hil_core_size(void) { return (int64_t)sizeof(hil_core_t); }
