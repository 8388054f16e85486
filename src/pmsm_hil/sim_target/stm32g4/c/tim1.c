/* TIM1, the advanced-control timer, in C: the same model, step for step, as the Python reference
 * (src/pmsm_hil/sim_target/stm32g4/peripherals/tim1.py, whose docstring says what is modelled), its state in one
 * fixed-size struct, its register page served by Unicorn MMIO callbacks of this library (no Python frame per
 * access of a hot register), its trigger outputs (TRGO, TRGO2, CC1-4) delivered to listeners in C (the ADCs, so no
 * Python runs between an update event and a conversion's start), its interrupt lines through a hil_irq_sink_t.
 * Built on first use by src/pmsm_hil/sim_target/stm32g4/periph_native.py. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "periph_ops.h"

#define W_CR1 (0x00 / 4)
#define W_CR2 (0x04 / 4)
#define W_SMCR (0x08 / 4)
#define W_DIER (0x0C / 4)
#define W_SR (0x10 / 4)
#define W_EGR (0x14 / 4)
#define W_CCMR1 (0x18 / 4)
#define W_CCMR2 (0x1C / 4)
#define W_CCER (0x20 / 4)
#define W_CNT (0x24 / 4)
#define W_PSC (0x28 / 4)
#define W_ARR (0x2C / 4)
#define W_RCR (0x30 / 4)
#define W_BDTR (0x44 / 4)
#define W_CCMR3 (0x50 / 4)
#define W_AF1 (0x60 / 4)
#define TIM1_WORDS 256
#define N_SIGNALS 6 /* TRGO, TRGO2, CC1, CC2, CC3, CC4 */
#define SIG_TRGO 0
#define SIG_TRGO2 1
#define SIG_CC1 2
#define MAX_LISTENERS 4
#define PWM1 6
#define PWM2 7
#define TOGGLE 3
#define BKE (1u << 12)
#define BKP (1u << 13)
#define AOE (1u << 14)
#define MOE (1u << 15)
#define BK2E (1u << 24)
#define BIF (1u << 7)
#define BKINE (1u << 0)
#define BKINP (1u << 9)

/* errors of hil_tim1_store (the Python side raises BoardError naming the field) */
#define TIM1_OK 0
#define TIM1_ERR_BK2E 1
#define TIM1_ERR_EGR 2
#define TIM1_ERR_SMS 3
#define TIM1_ERR_OPM 4

typedef void (*hil_listener_fn)(void *user, int signal, int rising, int64_t at);
typedef uint64_t (*hil_mmio_read_fn)(void *uc, uint64_t offset, unsigned size, void *user);
typedef void (*hil_mmio_write_fn)(void *uc, uint64_t offset, unsigned size, uint64_t value, void *user);

typedef struct {
    hil_listener_fn fn;
    void *user;
} hil_listener_t;

typedef struct {
    int64_t at;
    int32_t ch;
    int32_t pad;
} hil_match_t;

typedef struct hil_tim1 {
    uint32_t regs[TIM1_WORDS];     /* by word offset / 4 */
    uint8_t present[TIM1_WORDS];   /* 1: a modelled register */
    int64_t psc, arr, ccr[6], rep; /* active prescaler, auto-reload, compare values; repetition down-counter */
    int64_t seg_start, seg_from, seg_dir, done_until, frozen_cnt;
    int64_t updates, last_update, last_trigger, late_writes, first_late_update, late_counted_at;
    int64_t plan_end, break_trips;
    int32_t running, plan_valid, plan_n, plan_head, watched_valid, break_pin; /* break_pin -1: undriven */
    int32_t ocref[6];
    int32_t watched[6];
    hil_match_t plan[6];
    int32_t n_listeners[N_SIGNALS];
    hil_listener_t listeners[N_SIGNALS][MAX_LISTENERS];
    int32_t irq_up, irq_cc, irq_brk;
    int32_t lines_on[3]; /* which interrupt lines this model asserts */
    hil_irq_sink_t sink;
    const uint64_t *count; /* the core's cycle count (the instruction counter's) */
    hil_mmio_read_fn fallback_read;
    hil_mmio_write_fn fallback_write;
    void *fallback_user;
    hil_periph_ops_t ops;
} hil_tim1_t;

static int64_t floordiv(int64_t a, int64_t b) {
    int64_t q = a / b;
    return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

static int cms(const hil_tim1_t *t) { return (int)(t->regs[W_CR1] >> 5 & 3u); }
static int64_t tick(const hil_tim1_t *t) { return t->psc + 1; }

static int oc_mode(const hil_tim1_t *t, int ch) {
    uint32_t reg;
    int shift;
    if (ch < 4) {
        reg = t->regs[ch < 2 ? W_CCMR1 : W_CCMR2];
        shift = 8 * (ch & 1);
    } else {
        reg = t->regs[W_CCMR3];
        shift = 8 * (ch - 4);
    }
    return (int)((reg >> (shift + 4) & 7u) | (reg >> (shift + 16) & 1u) << 3);
}

static int preloaded(const hil_tim1_t *t, int ch) {
    if (ch < 4) {
        return (int)(t->regs[ch < 2 ? W_CCMR1 : W_CCMR2] >> (8 * (ch & 1) + 3) & 1u);
    }
    return (int)(t->regs[W_CCMR3] >> (8 * (ch - 4) + 3) & 1u);
}

/* each line asserted while a flag and its enable are set (pending it again), withdrawn when that ends */
static void irqs(hil_tim1_t *t) {
    uint32_t on = t->regs[W_SR] & t->regs[W_DIER];
    const int lines[3] = {t->irq_up, t->irq_cc, t->irq_brk};
    const uint32_t masks[3] = {1u, 0x1Eu, BIF};
    for (int i = 0; i < 3; ++i) {
        if (on & masks[i]) {
            t->lines_on[i] = 1;
            t->sink.assert_line(t->sink.board, lines[i]);
        } else if (t->lines_on[i]) {
            t->lines_on[i] = 0;
            t->sink.withdraw_line(t->sink.board, lines[i]);
        }
    }
}

static void flag(hil_tim1_t *t, uint32_t bits) {
    t->regs[W_SR] |= bits;
    irqs(t);
}

static void emit(hil_tim1_t *t, int signal, int rising, int64_t at) {
    for (int i = 0; i < t->n_listeners[signal]; ++i) {
        if (rising) {
            t->last_trigger = at;
        }
        t->listeners[signal][i].fn(t->listeners[signal][i].user, signal, rising, at);
    }
}

static void pulse(hil_tim1_t *t, int signal, int64_t at) {
    emit(t, signal, 1, at);
    emit(t, signal, 0, at);
}

static int observed(const hil_tim1_t *t, int ch) {
    uint32_t dier = t->regs[W_DIER];
    if (ch < 4 && (dier >> (ch + 1) & 1u)) {
        return 1;
    }
    if (ch < 4 && t->n_listeners[SIG_CC1 + ch]) {
        return 1;
    }
    int mms = (int)(t->regs[W_CR2] >> 4 & 7u), mms2 = (int)(t->regs[W_CR2] >> 20 & 0xFu);
    if (t->n_listeners[SIG_TRGO] && (mms == 4 + ch || (mms == 3 && ch == 0))) {
        return 1;
    }
    if (t->n_listeners[SIG_TRGO2]) {
        if (mms2 == 4 + ch || (mms2 == 3 && ch == 0)) {
            return 1;
        }
        if (ch == 3 && (mms2 == 10 || mms2 == 12 || mms2 == 13)) {
            return 1;
        }
        if (ch == 5 && mms2 >= 11 && mms2 <= 15) {
            return 1;
        }
        if (ch == 4 && (mms2 == 14 || mms2 == 15)) {
            return 1;
        }
    }
    return 0;
}

static void drop_plan(hil_tim1_t *t) { t->plan_valid = 0; }

static int64_t segment_ticks(const hil_tim1_t *t) {
    if (cms(t)) {
        return t->seg_dir > 0 ? t->arr - t->seg_from : t->seg_from;
    }
    return t->seg_dir > 0 ? t->arr + 1 - t->seg_from : t->seg_from + 1;
}

static int64_t segment_end(const hil_tim1_t *t) {
    int64_t ticks = segment_ticks(t);
    return t->seg_start + (ticks > 1 ? ticks : 1) * tick(t);
}

/* the current segment's observed matches after done_until: plan[plan_head .. plan_n) */
static void matches(hil_tim1_t *t) {
    if (!t->plan_valid) {
        int64_t end_ticks = segment_ticks(t);
        if (!t->watched_valid) {
            for (int ch = 0; ch < 6; ++ch) {
                t->watched[ch] = observed(t, ch);
            }
            t->watched_valid = 1;
        }
        int n = 0;
        for (int ch = 0; ch < 6; ++ch) {
            if (!t->watched[ch]) {
                continue;
            }
            int64_t c = t->ccr[ch];
            int64_t offset = t->seg_dir > 0 ? c - t->seg_from : t->seg_from - c;
            if (offset >= 0 && offset <= end_ticks && !(cms(t) && t->seg_dir < 0 && offset == 0)) {
                hil_match_t m = {t->seg_start + offset * tick(t), ch, 0};
                int i = n++;
                while (i > 0 && (t->plan[i - 1].at > m.at || (t->plan[i - 1].at == m.at && t->plan[i - 1].ch > ch))) {
                    t->plan[i] = t->plan[i - 1];
                    --i;
                }
                t->plan[i] = m;
            }
        }
        t->plan_n = n;
        t->plan_head = 0;
        t->plan_valid = 1;
        t->plan_end = segment_end(t);
    }
    while (t->plan_head < t->plan_n && t->plan[t->plan_head].at <= t->done_until) {
        ++t->plan_head;
    }
}

int64_t hil_tim1_next_event(void *self, int64_t now) {
    hil_tim1_t *t = (hil_tim1_t *)self;
    (void)now;
    if (!t->running) {
        return -1;
    }
    if (t->plan_valid && (t->plan_head == t->plan_n || t->plan[t->plan_head].at > t->done_until)) {
        if (t->plan_head < t->plan_n) {
            int64_t at = t->plan[t->plan_head].at;
            return at < t->plan_end ? at : t->plan_end;
        }
        return t->plan_end;
    }
    matches(t);
    int64_t end = segment_end(t);
    if (t->plan_head < t->plan_n) {
        int64_t at = t->plan[t->plan_head].at;
        return at < end ? at : end;
    }
    return end;
}

static void update(hil_tim1_t *t, int64_t at);

static int break_active(const hil_tim1_t *t) {
    uint32_t bdtr = t->regs[W_BDTR], af1 = t->regs[W_AF1];
    if (t->break_pin < 0 || !(bdtr & BKE) || !(af1 & BKINE)) {
        return 0;
    }
    return (t->break_pin != ((af1 & BKINP) != 0)) == ((bdtr & BKP) != 0);
}

static void match(hil_tim1_t *t, int ch, int64_t at) {
    int up = t->seg_dir > 0;
    int c = cms(t);
    if (ch < 4 && (c == 0 || c == 3 || (c == 1 && !up) || (c == 2 && up))) {
        flag(t, 1u << (ch + 1));
    }
    if (ch < 4) {
        pulse(t, SIG_CC1 + ch, at);
    }
    int mode = oc_mode(t, ch);
    int old = t->ocref[ch], now_level;
    if (mode == PWM1) {
        now_level = !up;
    } else if (mode == PWM2) {
        now_level = up;
    } else if (mode == TOGGLE) {
        now_level = !old;
    } else {
        now_level = old;
    }
    t->ocref[ch] = now_level;
    uint32_t cr2 = t->regs[W_CR2];
    int mms = (int)(cr2 >> 4 & 7u), mms2 = (int)(cr2 >> 20 & 0xFu);
    if (mms == 3 && ch == 0) {
        pulse(t, SIG_TRGO, at);
    }
    if (mms2 == 3 && ch == 0) {
        pulse(t, SIG_TRGO2, at);
    }
    if (now_level != old) {
        if (mms == 4 + ch) {
            emit(t, SIG_TRGO, now_level, at);
        }
        if (mms2 == 4 + ch) {
            emit(t, SIG_TRGO2, now_level, at);
        }
        if ((mms2 == 10 && ch == 3) || (mms2 == 11 && ch == 5)) {
            pulse(t, SIG_TRGO2, at);
        }
        if (now_level && (((mms2 == 12 || mms2 == 13) && ch == 3) || ((mms2 == 14 || mms2 == 15) && ch == 4))) {
            pulse(t, SIG_TRGO2, at);
        }
        if (ch == 5 && (((mms2 == 12 || mms2 == 14) && now_level) || ((mms2 == 13 || mms2 == 15) && !now_level))) {
            pulse(t, SIG_TRGO2, at);
        }
    }
}

static void segment_done(hil_tim1_t *t, int64_t at) {
    t->done_until = at;
    drop_plan(t);
    if (cms(t)) {
        if (t->seg_dir > 0) {
            t->seg_from = t->arr;
            t->seg_dir = -1;
        } else {
            t->seg_from = 0;
            t->seg_dir = 1;
        }
    } else {
        t->seg_from = t->seg_dir > 0 ? 0 : t->arr;
    }
    t->seg_start = at;
    if (t->rep == 0) {
        t->rep = t->regs[W_RCR];
        if (!(t->regs[W_CR1] >> 1 & 1u)) { /* UDIS */
            update(t, at);
            if (!cms(t)) {
                t->seg_from = t->seg_dir > 0 ? 0 : t->arr;
            }
        }
    } else {
        t->rep -= 1;
    }
}

static void update(hil_tim1_t *t, int64_t at) {
    static const int ccr_words[6] = {0x34 / 4, 0x38 / 4, 0x3C / 4, 0x40 / 4, 0x48 / 4, 0x4C / 4};
    t->psc = t->regs[W_PSC];
    t->arr = t->regs[W_ARR];
    for (int ch = 0; ch < 6; ++ch) {
        if (preloaded(t, ch)) {
            t->ccr[ch] = t->regs[ccr_words[ch]];
        }
    }
    t->updates += 1;
    t->last_update = at;
    if ((t->regs[W_BDTR] & AOE) && !(t->regs[W_BDTR] & MOE) && !break_active(t)) {
        t->regs[W_BDTR] |= MOE;
    }
    flag(t, 1u);
    uint32_t cr2 = t->regs[W_CR2];
    if ((cr2 >> 4 & 7u) == 2u) {
        pulse(t, SIG_TRGO, at);
    }
    if ((cr2 >> 20 & 0xFu) == 2u) {
        pulse(t, SIG_TRGO2, at);
    }
}

void hil_tim1_advance(void *self, int64_t now) {
    hil_tim1_t *t = (hil_tim1_t *)self;
    if (t->plan_valid && t->running && t->plan_end > now &&
        (t->plan_head == t->plan_n || t->plan[t->plan_head].at > now)) {
        if (now > t->done_until) {
            t->done_until = now;
        }
        return;
    }
    while (t->running) {
        int64_t ticks = segment_ticks(t);
        int64_t end = t->seg_start + (ticks > 1 ? ticks : 1) * tick(t);
        matches(t);
        while (t->plan_head < t->plan_n && t->plan[t->plan_head].at <= now) {
            hil_match_t m = t->plan[t->plan_head++];
            match(t, m.ch, m.at);
            t->done_until = m.at;
        }
        if (end > now) {
            if (now > t->done_until) {
                t->done_until = now;
            }
            return;
        }
        segment_done(t, end);
    }
}

int64_t hil_tim1_counter(hil_tim1_t *t, int64_t now) {
    if (!t->running) {
        return t->frozen_cnt;
    }
    hil_tim1_advance(t, now);
    int64_t ticks = floordiv(now - t->seg_start, tick(t));
    return t->seg_from + t->seg_dir * ticks;
}

void hil_tim1_trip_break(hil_tim1_t *t) {
    t->regs[W_BDTR] &= ~MOE;
    t->regs[W_SR] |= BIF;
    t->break_trips += 1;
    irqs(t);
}

int hil_tim1_break_active(const hil_tim1_t *t) { return break_active(t); }

void hil_tim1_set_break_pin(hil_tim1_t *t, int level, int64_t now) {
    hil_tim1_advance(t, now);
    int was = break_active(t);
    t->break_pin = level ? 1 : 0;
    if (break_active(t) && !was) {
        hil_tim1_trip_break(t);
    }
}

static void restart(hil_tim1_t *t, int64_t now, int64_t cnt) {
    drop_plan(t);
    t->frozen_cnt = cnt;
    t->seg_start = now;
    t->seg_from = cnt;
    t->seg_dir = (!cms(t) && (t->regs[W_CR1] >> 4 & 1u)) ? -1 : 1;
    if (cms(t) && cnt >= t->arr) {
        t->seg_dir = -1;
    }
    t->done_until = now;
}

static void note_compare_write(hil_tim1_t *t) {
    if (t->last_trigger < 0 || t->last_update <= t->last_trigger || !t->running) {
        return;
    }
    if (t->late_counted_at == t->last_update) {
        return;
    }
    t->late_counted_at = t->last_update;
    t->late_writes += 1;
    if (t->first_late_update < 0) {
        t->first_late_update = t->updates;
    }
}

uint32_t hil_tim1_load(hil_tim1_t *t, int word, int64_t now) {
    if (word == W_SR || word == W_CNT) {
        hil_tim1_advance(t, now);
    }
    if (word == W_CNT) {
        return (uint32_t)hil_tim1_counter(t, now) & 0xFFFFu;
    }
    if (word == W_EGR) {
        return 0u;
    }
    if (word == W_CR1) {
        return (t->regs[W_CR1] & ~(1u << 4)) | (t->seg_dir < 0 ? 1u << 4 : 0u);
    }
    return t->regs[word];
}

static int ccr_channel(int word) {
    switch (word) {
    case 0x34 / 4: return 0;
    case 0x38 / 4: return 1;
    case 0x3C / 4: return 2;
    case 0x40 / 4: return 3;
    case 0x48 / 4: return 4;
    case 0x4C / 4: return 5;
    default: return -1;
    }
}

static int plan_word(int word) {
    return word == W_CR1 || word == W_CR2 || word == W_SMCR || word == W_DIER || word == W_CCMR1 ||
           word == W_CCMR2 || word == W_CCMR3 || word == W_CCER || word == W_CNT || word == W_PSC || word == W_ARR;
}

int hil_tim1_store(hil_tim1_t *t, int word, uint32_t value, int64_t now) {
    hil_tim1_advance(t, now);
    int ch = ccr_channel(word);
    if (plan_word(word) || (ch >= 0 && !preloaded(t, ch))) {
        drop_plan(t);
        t->watched_valid = 0;
    }
    if (word == W_SR) { /* rc_w0; BIF stays set while BRK is active */
        t->regs[W_SR] &= value | (break_active(t) ? BIF : 0u);
        irqs(t);
        return TIM1_OK;
    }
    if (word == W_BDTR) {
        if (value & BK2E) {
            return TIM1_ERR_BK2E;
        }
        int was = break_active(t);
        t->regs[W_BDTR] = value;
        if (break_active(t)) {
            t->regs[W_BDTR] &= ~MOE;
            if (!was) {
                hil_tim1_trip_break(t);
            }
        }
        return TIM1_OK;
    }
    if (word == W_EGR) {
        if (value & 1u) {
            restart(t, now, (!(t->regs[W_CR1] >> 4 & 1u) || cms(t)) ? 0 : (int64_t)t->regs[W_ARR]);
            t->rep = t->regs[W_RCR];
            update(t, now);
        }
        if (value & ~1u & 0xFFu) {
            return TIM1_ERR_EGR;
        }
        return TIM1_OK;
    }
    if (word == W_CNT) {
        restart(t, now, value & 0xFFFFu);
        return TIM1_OK;
    }
    if (word == W_SMCR && (value & 0x00010007u)) {
        return TIM1_ERR_SMS;
    }
    if (word == W_CR1) {
        if (value & 8u) {
            return TIM1_ERR_OPM;
        }
        int was = t->running;
        uint32_t old_dir = t->regs[W_CR1] >> 4 & 1u;
        t->regs[W_CR1] = value & 0x1FFFu;
        if (!(t->regs[W_CR1] >> 7 & 1u)) {
            t->arr = t->regs[W_ARR];
        }
        if ((value & 1u) && !was) {
            t->running = 1;
            restart(t, now, t->frozen_cnt);
        } else if (!(value & 1u) && was) {
            t->frozen_cnt = hil_tim1_counter(t, now);
            t->running = 0;
        } else if (!cms(t) && (value >> 4 & 1u) != old_dir) {
            restart(t, now, hil_tim1_counter(t, now));
        }
        return TIM1_OK;
    }
    if (word == W_DIER) {
        t->regs[W_DIER] = value;
        irqs(t);
        return TIM1_OK;
    }
    if (ch >= 0) {
        t->regs[word] = value & 0xFFFFu;
        if (ch < 3) {
            note_compare_write(t);
        }
        if (!preloaded(t, ch)) {
            t->ccr[ch] = value & 0xFFFFu;
        }
        return TIM1_OK;
    }
    if (word == W_ARR) {
        t->regs[W_ARR] = value & 0xFFFFu;
        if (!(t->regs[W_CR1] >> 7 & 1u)) {
            t->arr = value & 0xFFFFu;
        }
        return TIM1_OK;
    }
    t->regs[word] = value;
    return TIM1_OK;
}

/* listeners: a trigger signal's subscribers, called in subscription order */
int hil_tim1_subscribe(hil_tim1_t *t, int signal, hil_listener_fn fn, void *user) {
    if (signal < 0 || signal >= N_SIGNALS) {
        return -1;
    }
    for (int i = 0; i < t->n_listeners[signal]; ++i) {
        if (t->listeners[signal][i].fn == fn && t->listeners[signal][i].user == user) {
            drop_plan(t);
            t->watched_valid = 0;
            return 0;
        }
    }
    if (t->n_listeners[signal] >= MAX_LISTENERS) {
        return -2;
    }
    t->listeners[signal][t->n_listeners[signal]++] = (hil_listener_t){fn, user};
    drop_plan(t);
    t->watched_valid = 0;
    return 0;
}

void hil_tim1_unsubscribe(hil_tim1_t *t, hil_listener_fn fn, void *user) {
    for (int s = 0; s < N_SIGNALS; ++s) {
        int n = 0;
        for (int i = 0; i < t->n_listeners[s]; ++i) {
            if (!(t->listeners[s][i].fn == fn && t->listeners[s][i].user == user)) {
                t->listeners[s][n++] = t->listeners[s][i];
            }
        }
        t->n_listeners[s] = n;
    }
    drop_plan(t);
    t->watched_valid = 0;
}

/* The register page as Unicorn MMIO callbacks (`user` the model, offsets from the page's base 0x40012000): every
 * read of a modelled register, and the writes that cannot move the model's events (SR, a preloaded CCRx), in C,
 * each reported to the sink's `touched` when it has one (a scheduler in C);
 * every other access through the fallback (the Python model behind the board's decoder, which names an unmodelled
 * register and re-makes the schedule). */
#define TIM1_PAGE_OFFSET 0xC00u

uint64_t hil_tim1_mmio_read(void *uc, uint64_t offset, unsigned size, void *user) {
    hil_tim1_t *t = (hil_tim1_t *)user;
    if (offset >= TIM1_PAGE_OFFSET && size <= 4u) {
        unsigned off = (unsigned)(offset - TIM1_PAGE_OFFSET);
        int word = (int)(off >> 2);
        if (word < TIM1_WORDS && t->present[word]) {
            return hil_served_read(&t->sink, t, hil_tim1_load(t, word, (int64_t)*t->count), off, size);
        }
    }
    return t->fallback_read(uc, offset, size, t->fallback_user);
}

void hil_tim1_mmio_write(void *uc, uint64_t offset, unsigned size, uint64_t value, void *user) {
    hil_tim1_t *t = (hil_tim1_t *)user;
    if (offset >= TIM1_PAGE_OFFSET && size <= 4u) {
        unsigned off = (unsigned)(offset - TIM1_PAGE_OFFSET);
        int word = (int)(off >> 2);
        int ch = word < TIM1_WORDS ? ccr_channel(word) : -1;
        if (word == W_SR || (ch >= 0 && preloaded(t, ch))) {
            int64_t now = (int64_t)*t->count;
            uint32_t old = hil_tim1_load(t, word, now);
            hil_tim1_store(t, word, hil_reg_merge(old, off, size, (uint32_t)value), now);
            if (t->sink.touched) {
                t->sink.touched(t->sink.board, t, 1);
            }
            return;
        }
    }
    t->fallback_write(uc, offset, size, value, t->fallback_user);
}

/* BDTR.DTG as seconds with tDTS from CR1.CKD (the Python reference's Tim1.dead_time_s, operation for operation) */
static double dead_time_s(const hil_tim1_t *t, double hclk_hz) {
    static const double ckd[4] = {1.0, 2.0, 4.0, 4.0};
    const uint32_t dtg = t->regs[W_BDTR] & 0xFFu;
    const double t_dts = ckd[t->regs[W_CR1] >> 8 & 3u] / hclk_hz;
    if (dtg >> 7 == 0u) {
        return (double)dtg * t_dts;
    }
    if (dtg >> 6 == 2u) {
        return (double)((64u + (dtg & 0x3Fu)) * 2u) * t_dts;
    }
    if (dtg >> 5 == 6u) {
        return (double)((32u + (dtg & 0x1Fu)) * 8u) * t_dts;
    }
    return (double)((32u + (dtg & 0x1Fu)) * 16u) * t_dts;
}

/* OCx's active-high share of a carrier period with the compare value in force (Tim1.duty) */
static double duty(const hil_tim1_t *t, int ch) {
    const int mode = oc_mode(t, ch);
    const int64_t span = cms(t) ? t->arr : t->arr + 1;
    double ref_high = 0.0;
    if (span) {
        ref_high = (double)t->ccr[ch] / (double)span;
        ref_high = ref_high < 0.0 ? 0.0 : ref_high;
        ref_high = ref_high > 1.0 ? 1.0 : ref_high;
    }
    if (mode == PWM2) {
        ref_high = 1.0 - ref_high;
    } else if (mode != PWM1) {
        ref_high = mode == 5 ? 1.0 : 0.0; /* forced active / anything else inactive */
    }
    if (t->regs[W_CCER] >> (4 * ch + 1) & 1u) { /* CCxP: active low */
        ref_high = 1.0 - ref_high;
    }
    return ref_high;
}

/* The outputs a board link reads once a period (Tim1.compare_duties, the Python reference): with MOE set, the
 * duties of channels[0..n) (0-based) with the compare values in force, each shortened or lengthened by the dead
 * time by the sign of currents[k] [A] when its complementary output is on, clamped to 0..1, into out: 1; MOE clear:
 * 0, out untouched. hclk_hz [Hz], carrier_s [s]. */
int hil_tim1_compare_duties(const hil_tim1_t *t, int n, const int32_t *channels, const double *currents,
                            double hclk_hz, double carrier_s, double *out) {
    double dead;
    if (!(t->regs[W_BDTR] & MOE)) {
        return 0;
    }
    dead = dead_time_s(t, hclk_hz) / carrier_s;
    for (int k = 0; k < n; ++k) {
        const int ch = channels[k];
        double d = t->regs[W_CCER] >> (4 * ch) & 1u ? duty(t, ch) : 0.5;
        if ((t->regs[W_CCER] >> (4 * ch + 2) & 1u) && dead != 0.0 && currents[k] != 0.0) {
            d -= signbit(currents[k]) ? -dead : dead;
        }
        d = d < 0.0 ? 0.0 : d;
        out[k] = d > 1.0 ? 1.0 : d;
    }
    return 1;
}

/* hil_tim1_compare_duties' arguments but the currents, for a board link that calls it without Python */
typedef struct {
    const hil_tim1_t *tim;
    int32_t n;
    int32_t channels[6];
    double hclk_hz, carrier_s;
} hil_tim1_outputs_t;

/* hil_tim1_compare_duties for the outputs `user` (a hil_tim1_outputs_t): 1 with out filled, 0 with MOE clear */
int hil_tim1_outputs(void *user, const double *currents, double *out) {
    const hil_tim1_outputs_t *o = (const hil_tim1_outputs_t *)user;
    return hil_tim1_compare_duties(o->tim, o->n, o->channels, currents, o->hclk_hz, o->carrier_s, out);
}

unsigned hil_tim1_outputs_size(void) { return (unsigned)sizeof(hil_tim1_outputs_t); }

/* set-up: reset values, the sink, the counter; `ops` for a scheduler in C */
void hil_tim1_init(hil_tim1_t *t) {
    t->ops.self = t;
    t->ops.next_event = hil_tim1_next_event;
    t->ops.advance = hil_tim1_advance;
}

unsigned hil_tim1_size(void) { return (unsigned)sizeof(hil_tim1_t); }
