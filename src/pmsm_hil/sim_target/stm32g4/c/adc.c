/* ADC1 and ADC2 in C: the same model, step for step, as the Python reference
 * (src/pmsm_hil/sim_target/stm32g4/peripherals/adc.py, whose docstring says what is modelled), the pair's state in
 * one fixed-size struct (the two ADCs share the ADC1_2 interrupt line and their register page), served by Unicorn
 * MMIO callbacks of this library; a TIM1 trigger reaches `hil_adc_on_trigger` straight from the timer's library.
 * What stays with the caller, through function pointers: a conversion's code (the board's analog front end) and a
 * regular conversion's DMA request. Built on first use by src/pmsm_hil/sim_target/stm32g4/periph_native.py. */
#include <stdint.h>
#include <string.h>

#include "periph_ops.h"

#define ADC_WORDS 64
#define TABLE_CHANNELS 32
#define QUEUE_MAX 64
#define LOG_MAX 64
#define W_ISR (0x00 / 4)
#define W_IER (0x04 / 4)
#define W_CR (0x08 / 4)
#define W_CFGR (0x0C / 4)
#define W_SMPR1 (0x14 / 4)
#define W_SMPR2 (0x18 / 4)
#define W_SQR1 (0x30 / 4)
#define W_DR (0x40 / 4)
#define W_JSQR (0x4C / 4)
#define W_JDR (0x80 / 4)
#define W_CALFACT (0xB4 / 4)
#define ADRDY 1u
#define EOSMP 2u
#define EOC 4u
#define EOS 8u
#define OVR 16u
#define JEOC 32u
#define JEOS 64u
#define ADEN 1u
#define ADDIS 2u
#define ADSTART 4u
#define JADSTART 8u
#define ADSTP 16u
#define JADSTP 32u
#define ADVREGEN (1u << 28)
#define DEEPPWD (1u << 29)
#define ADCAL (1u << 31)
#define DMAEN 1u
#define CONVERT_CLOCKS 12.5
#define CALIBRATION_CLOCKS 116.0
#define READY_CLOCKS 4.0

/* refusals of hil_adc_store (the Python side raises BoardError naming the field) */
#define ADC_OK 0
#define ADC_ERR_CAL_ENABLED 1
#define ADC_ERR_CAL_REGULATOR 2
#define ADC_ERR_QUEUE 3

/* TIM1's trigger signals (c/tim1.c's order) */
#define SIG_TRGO 0
#define SIG_TRGO2 1
#define SIG_CC1 2
#define SIG_CC4 5

typedef uint32_t (*hil_adc_code_fn)(void *user, int adc, int channel, int64_t at);
typedef void (*hil_adc_dma_fn)(void *user, int adc, int64_t at);
typedef uint64_t (*hil_mmio_read_fn)(void *uc, uint64_t offset, unsigned size, void *user);
typedef void (*hil_mmio_write_fn)(void *uc, uint64_t offset, unsigned size, uint64_t value, void *user);

typedef struct {
    int64_t sample_at, done_at;
    int32_t injected, rank, channel, last;
} hil_conv_t;

typedef struct {
    int64_t at;
    int32_t channel;
    uint32_t code;
} hil_sample_t;

struct hil_adc12;

typedef struct hil_adc {
    uint32_t regs[ADC_WORDS];
    uint8_t present[ADC_WORDS];
    int64_t cal_done_at, ready_at; /* -1: none */
    int64_t triggers, samples;     /* injected triggers taken; injected samples logged so far */
    int32_t ready, index, n_queue, error;
    hil_conv_t queue[QUEUE_MAX];
    hil_sample_t log[LOG_MAX]; /* the recent injected samples: entry `samples % LOG_MAX` is the next */
    struct hil_adc12 *pair;
} hil_adc_t;

typedef struct hil_adc12 {
    hil_adc_t adc[2];
    uint32_t common_ccr; /* ADC12_COMMON.CCR (the clock) */
    int32_t irq;         /* ADC1_2 */
    int32_t line_on;     /* ADC1_2 asserted by the pair */
    /* the analog front end as a table the board's link fills once a period (table_on): each input's voltage and
     * VREF+ [V]; else each conversion's code comes from `code` (the board's analog front end in Python: noise, the
     * OPAMPs) */
    int32_t table_on;
    double vref;
    double volts[2][TABLE_CHANNELS];
    hil_irq_sink_t sink;
    hil_adc_code_fn code;
    hil_adc_dma_fn dma;
    void *callback_user;
    const uint64_t *count;
    hil_mmio_read_fn fallback_read;
    hil_mmio_write_fn fallback_write;
    void *fallback_user;
    hil_periph_ops_t ops[2];
} hil_adc12_t;

static const double SAMPLE_CLOCKS[8] = {2.5, 6.5, 12.5, 24.5, 47.5, 92.5, 247.5, 640.5};
static const int ASYNC_PRESC[12] = {1, 2, 4, 6, 8, 10, 12, 16, 32, 64, 128, 256};

/* Python's round() of a non-negative time: to the nearest integer, halves to even */
static int64_t round_even(double x) {
    int64_t i = (int64_t)x;
    double frac = x - (double)i;
    if (frac > 0.5 || (frac == 0.5 && (i & 1))) {
        i += 1;
    }
    return i;
}

static void line_changed(hil_adc12_t *p) {
    int on = 0;
    for (int i = 0; i < 2; ++i) {
        if (p->adc[i].regs[W_ISR] & p->adc[i].regs[W_IER] & 0x7FFu) {
            on = 1;
        }
    }
    if (on) {
        p->line_on = 1;
        p->sink.assert_line(p->sink.board, p->irq);
    } else if (p->line_on) {
        p->line_on = 0;
        p->sink.withdraw_line(p->sink.board, p->irq);
    }
}

static void set_flags(hil_adc_t *a, uint32_t bits) {
    a->regs[W_ISR] |= bits;
    line_changed(a->pair);
}

double hil_adc_cycles_per_clock(const hil_adc_t *a) {
    uint32_t ccr = a->pair->common_ccr;
    uint32_t ckmode = ccr >> 16 & 3u;
    if (ckmode) {
        static const double per[4] = {1.0, 1.0, 2.0, 4.0};
        return per[ckmode];
    }
    uint32_t presc = ccr >> 18 & 0xFu;
    return (double)(presc < 12u ? ASYNC_PRESC[presc] : 256);
}

static double sample_clocks(const hil_adc_t *a, int channel) {
    uint32_t reg = channel < 10 ? a->regs[W_SMPR1] : a->regs[W_SMPR2];
    int shift = 3 * (channel < 10 ? channel : channel - 10);
    return SAMPLE_CLOCKS[shift < 32 ? (reg >> shift & 7u) : 0u];
}

static int sequence(const hil_adc_t *a, int injected, int *out) {
    if (injected) {
        uint32_t jsqr = a->regs[W_JSQR];
        int n = (int)(jsqr & 3u) + 1;
        for (int i = 0; i < n; ++i) {
            out[i] = (int)(jsqr >> (9 + 6 * i) & 0x1Fu);
        }
        return n;
    }
    int n = (int)(a->regs[W_SQR1] & 0xFu) + 1;
    for (int rank = 0; rank < n; ++rank) {
        int pos = rank + 1;
        out[rank] = (int)(a->regs[W_SQR1 + pos / 5] >> (6 * (pos % 5)) & 0x1Fu);
    }
    return n;
}

static void sort_queue(hil_adc_t *a) { /* stable, by done_at */
    for (int i = 1; i < a->n_queue; ++i) {
        hil_conv_t c = a->queue[i];
        int j = i;
        while (j > 0 && a->queue[j - 1].done_at > c.done_at) {
            a->queue[j] = a->queue[j - 1];
            --j;
        }
        a->queue[j] = c;
    }
}

static void drop_group(hil_adc_t *a, int injected) {
    int n = 0;
    for (int i = 0; i < a->n_queue; ++i) {
        if (a->queue[i].injected != injected) {
            a->queue[n++] = a->queue[i];
        }
    }
    a->n_queue = n;
}

static void start(hil_adc_t *a, int injected, int64_t at) {
    if (!a->ready || !(a->regs[W_CR] & ADEN)) {
        return;
    }
    double per_clock = hil_adc_cycles_per_clock(a);
    double t = a->n_queue == 0 ? (double)at : (double)a->queue[a->n_queue - 1].done_at;
    int channels[16];
    int n = sequence(a, injected, channels);
    if (injected) {
        drop_group(a, 1);
        t = (double)at;
    }
    for (int rank = 0; rank < n; ++rank) {
        double sample = t + sample_clocks(a, channels[rank]) * per_clock;
        double done = sample + CONVERT_CLOCKS * per_clock;
        if (a->n_queue >= QUEUE_MAX) {
            a->error = ADC_ERR_QUEUE;
            break;
        }
        hil_conv_t c = {round_even(sample), round_even(done), injected, rank, channels[rank], rank == n - 1};
        a->queue[a->n_queue++] = c;
        t = done;
    }
    sort_queue(a);
}

/* Python's round() of a float: to the nearest integer, halves to even */
static int64_t round_half_even(double x) {
    if (x < 0.0) {
        return -round_even(-x);
    }
    return round_even(x);
}

/* the code of `volts` with VREF+ `vref` at CFGR's resolution and alignment (the Python reference's Adc._code) */
uint32_t hil_adc_code_of(const hil_adc_t *a, double volts, double vref) {
    static const int bits_of[4] = {12, 10, 8, 6};
    int bits = bits_of[a->regs[W_CFGR] >> 3 & 3u];
    int64_t full = ((int64_t)1 << bits) - 1;
    int64_t code = round_half_even(volts / vref * (double)full);
    code = code < 0 ? 0 : code > full ? full : code;
    if (a->regs[W_CFGR] >> 15 & 1u) { /* ALIGN left */
        code <<= bits > 6 ? 16 - bits : 8 - bits;
    }
    return (uint32_t)code;
}

static void finish(hil_adc_t *a, hil_conv_t conv) {
    hil_adc12_t *p = a->pair;
    uint32_t code = p->table_on && conv.channel < TABLE_CHANNELS
                        ? hil_adc_code_of(a, p->volts[a->index][conv.channel], p->vref)
                        : p->code(p->callback_user, a->index, conv.channel, conv.sample_at);
    uint32_t flags;
    if (conv.injected) {
        a->regs[W_JDR + conv.rank] = code;
        hil_sample_t *s = &a->log[a->samples % LOG_MAX];
        s->at = conv.sample_at;
        s->channel = conv.channel;
        s->code = code;
        a->samples += 1;
        flags = JEOC | (conv.last ? JEOS : 0u);
        if (conv.last && !(a->regs[W_JSQR] >> 7 & 3u)) {
            a->regs[W_CR] &= ~JADSTART;
        }
    } else {
        if ((a->regs[W_ISR] & EOC) && !(a->regs[W_CFGR] >> 12 & 1u)) {
            set_flags(a, OVR);
        }
        a->regs[W_DR] = code;
        flags = EOC | (conv.last ? EOS : 0u);
        if (conv.last && !(a->regs[W_CFGR] >> 10 & 3u) && !(a->regs[W_CFGR] >> 13 & 1u)) {
            a->regs[W_CR] &= ~ADSTART;
        } else if (conv.last && (a->regs[W_CFGR] >> 13 & 1u) && (a->regs[W_CR] & ADSTART)) {
            start(a, 0, conv.done_at);
        }
    }
    set_flags(a, flags | EOSMP);
    if (!conv.injected && (a->regs[W_CFGR] & DMAEN)) {
        p->dma(p->callback_user, a->index, conv.done_at);
    }
}

int64_t hil_adc_next_event(void *self, int64_t now) {
    const hil_adc_t *a = (const hil_adc_t *)self;
    (void)now;
    int64_t best = a->n_queue ? a->queue[0].done_at : -1;
    if (a->cal_done_at >= 0 && (best < 0 || a->cal_done_at < best)) {
        best = a->cal_done_at;
    }
    if (a->ready_at >= 0 && (best < 0 || a->ready_at < best)) {
        best = a->ready_at;
    }
    return best;
}

void hil_adc_advance(void *self, int64_t now) {
    hil_adc_t *a = (hil_adc_t *)self;
    if (a->cal_done_at >= 0 && now >= a->cal_done_at) {
        a->cal_done_at = -1;
        a->regs[W_CR] &= ~ADCAL;
        a->regs[W_CALFACT] = 0x00410041u;
    }
    if (a->ready_at >= 0 && now >= a->ready_at) {
        a->ready_at = -1;
        a->ready = 1;
        set_flags(a, ADRDY);
    }
    while (a->n_queue && a->queue[0].done_at <= now) {
        hil_conv_t conv = a->queue[0];
        memmove(&a->queue[0], &a->queue[1], (size_t)(a->n_queue - 1) * sizeof(hil_conv_t));
        a->n_queue -= 1;
        finish(a, conv);
    }
}

/* an edge of TIM1's `signal` (c/tim1.c's listener) */
void hil_adc_on_trigger(void *user, int signal, int rising, int64_t at) {
    hil_adc_t *a = (hil_adc_t *)user;
    uint32_t cr = a->regs[W_CR];
    uint32_t jedge = a->regs[W_JSQR] >> 7 & 3u, edge = a->regs[W_CFGR] >> 10 & 3u;
    for (int injected = 1; injected >= 0; --injected) {
        uint32_t start_bit = injected ? JADSTART : ADSTART, field = injected ? jedge : edge;
        if (!(cr & start_bit) || !field) {
            continue;
        }
        int sel = injected ? (int)(a->regs[W_JSQR] >> 2 & 0x1Fu) : (int)(a->regs[W_CFGR] >> 5 & 0x1Fu);
        int wanted;
        if (injected) {
            wanted = sel == 0 ? SIG_TRGO : sel == 1 ? SIG_CC4 : sel == 8 ? SIG_TRGO2 : -1;
        } else {
            wanted = sel <= 2 ? SIG_CC1 + sel : sel == 9 ? SIG_TRGO : sel == 10 ? SIG_TRGO2 : -1;
        }
        if (wanted != signal) {
            continue;
        }
        if ((field == 1u && rising) || (field == 2u && !rising) || field == 3u) {
            if (injected) {
                a->triggers += 1;
            }
            start(a, injected, at);
        }
    }
}

uint32_t hil_adc_load(hil_adc_t *a, int word, int64_t now) {
    hil_adc_advance(a, now);
    if (word == W_DR && (a->regs[W_ISR] & EOC)) {
        a->regs[W_ISR] &= ~EOC;
        line_changed(a->pair);
    }
    return a->regs[word];
}

static int control(hil_adc_t *a, uint32_t value, int64_t now) {
    uint32_t cr = a->regs[W_CR];
    double per_clock = hil_adc_cycles_per_clock(a);
    uint32_t keep = cr & (ADCAL | ADSTART | JADSTART | ADEN);
    uint32_t next = (value & (ADVREGEN | DEEPPWD | (1u << 30))) | keep;
    if ((value & ADCAL) && !(cr & ADCAL)) {
        if (cr & ADEN) {
            return ADC_ERR_CAL_ENABLED;
        }
        if (!(value & ADVREGEN) || (value & DEEPPWD)) {
            return ADC_ERR_CAL_REGULATOR;
        }
        next |= ADCAL;
        a->cal_done_at = now + round_even(CALIBRATION_CLOCKS * per_clock);
    }
    if ((value & ADEN) && !(cr & ADEN)) {
        next |= ADEN;
        a->ready_at = now + round_even(READY_CLOCKS * per_clock);
    }
    if ((value & ADDIS) && (cr & ADEN)) {
        next &= ~(ADEN | ADSTART | JADSTART);
        a->regs[W_ISR] &= ~ADRDY;
        a->ready = 0;
        a->ready_at = -1;
        a->n_queue = 0;
    }
    if (value & JADSTP) {
        next &= ~JADSTART;
        drop_group(a, 1);
    }
    if (value & ADSTP) {
        next &= ~ADSTART;
        drop_group(a, 0);
    }
    a->regs[W_CR] = next;
    if ((value & JADSTART) && (next & ADEN)) {
        a->regs[W_CR] |= JADSTART;
        if (!(a->regs[W_JSQR] >> 7 & 3u)) {
            start(a, 1, now);
        }
    }
    if ((value & ADSTART) && (next & ADEN)) {
        a->regs[W_CR] |= ADSTART;
        if (!(a->regs[W_CFGR] >> 10 & 3u)) {
            start(a, 0, now);
        }
    }
    return ADC_OK;
}

/* a store to a modelled register (JSQR and CFGR: the caller re-subscribes to TIM1's signals) */
int hil_adc_store(hil_adc_t *a, int word, uint32_t value, int64_t now) {
    hil_adc_advance(a, now);
    if (word == W_ISR) {
        a->regs[W_ISR] &= ~value;
        line_changed(a->pair);
        return ADC_OK;
    }
    if (word == W_IER) {
        a->regs[W_IER] = value & 0x7FFu;
        line_changed(a->pair);
        return ADC_OK;
    }
    if (word == W_CR) {
        return control(a, value, now);
    }
    if (word == W_DR || (word >= W_JDR && word < W_JDR + 4)) {
        return ADC_OK;
    }
    a->regs[word] = value;
    return ADC_OK;
}

/* The page 0x50000000 as Unicorn MMIO callbacks (`user` the pair): ADC1 at 0x000, ADC2 at 0x100; every read of a
 * modelled register and the writes of ISR (which cannot move an event) in C (each reported to the sink's `touched`
 * when it has one: a scheduler in C), every other access (ADC12_COMMON, a
 * control or configuration register, an unmodelled offset) through the fallback: the board's decoder and the
 * Python side of the model. */
uint64_t hil_adc_mmio_read(void *uc, uint64_t offset, unsigned size, void *user) {
    hil_adc12_t *p = (hil_adc12_t *)user;
    if (offset < 0x200u && size <= 4u) {
        hil_adc_t *a = &p->adc[offset >> 8];
        unsigned off = (unsigned)(offset & 0xFFu);
        int word = (int)(off >> 2);
        if (a->present[word] && !a->error) {
            return hil_served_read(&p->sink, a, hil_adc_load(a, word, (int64_t)*p->count), off, size);
        }
    }
    return p->fallback_read(uc, offset, size, p->fallback_user);
}

void hil_adc_mmio_write(void *uc, uint64_t offset, unsigned size, uint64_t value, void *user) {
    hil_adc12_t *p = (hil_adc12_t *)user;
    if (offset < 0x200u && size <= 4u && ((offset & 0xFFu) >> 2) == W_ISR) {
        hil_adc_t *a = &p->adc[offset >> 8];
        if (!a->error) {
            int64_t now = (int64_t)*p->count;
            uint32_t old = hil_adc_load(a, W_ISR, now);
            hil_adc_store(a, W_ISR, hil_reg_merge(old, (unsigned)(offset & 0xFFu), size, (uint32_t)value), now);
            if (p->sink.touched) {
                p->sink.touched(p->sink.board, a, 1);
            }
            return;
        }
    }
    p->fallback_write(uc, offset, size, value, p->fallback_user);
}

/* offset + gain x value rounded twice, as Python computes it (no fused multiply-add on a target that has one) */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

/* A board's analog front end without noise, for the pair's table (a board link's, once a period): input k < n on
 * ADC adc[k] (0 ADC1, 1 ADC2) channel channel[k] (< TABLE_CHANNELS, checked by the caller that fills this) at
 * offset[k] + gain[k] x the value of signal signal[k]; VREF+ vref and VREFINT (ADC1 IN18) vrefint [V]. */
#define FRONT_MAX 32
typedef struct {
    hil_adc12_t *pair;
    int32_t n;
    int32_t adc[FRONT_MAX], channel[FRONT_MAX], signal[FRONT_MAX];
    double offset[FRONT_MAX], gain[FRONT_MAX];
    double vref, vrefint;
} hil_adc_front_t;

/* The pair's inputs for a period at the signal values `values` (the front end `user`'s signals), in place of
 * filling the table from Python: every pin at 0 V, then each input in order (a later one on the same pin wins),
 * then VREFINT on ADC1 IN18; VREF+; the table on. */
void hil_adc_front_take(void *user, const double *values) {
    const hil_adc_front_t *f = (const hil_adc_front_t *)user;
    hil_adc12_t *p = f->pair;
    memset(p->volts, 0, sizeof p->volts);
    for (int k = 0; k < f->n; ++k) {
        p->volts[f->adc[k]][f->channel[k]] = f->offset[k] + f->gain[k] * values[f->signal[k]];
    }
    p->volts[0][18] = f->vrefint;
    p->vref = f->vref;
    p->table_on = 1;
}

unsigned hil_adc_front_size(void) { return (unsigned)sizeof(hil_adc_front_t); }

void hil_adc_init(hil_adc12_t *p) {
    for (int i = 0; i < 2; ++i) {
        p->adc[i].pair = p;
        p->adc[i].index = i;
        p->ops[i].self = &p->adc[i];
        p->ops[i].next_event = hil_adc_next_event;
        p->ops[i].advance = hil_adc_advance;
    }
}

unsigned hil_adc_size(void) { return (unsigned)sizeof(hil_adc12_t); }
unsigned hil_adc_one_size(void) { return (unsigned)sizeof(hil_adc_t); }
