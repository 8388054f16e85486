/* The encoder timer's CNT read in C: the page of TIM2-TIM5 (0x40000000) as a Unicorn MMIO callback of this library
 * that answers a read of the armed timer's CNT while it counts the board's encoder (SMCR.SMS 1-3), as
 * src/pmsm_hil/sim_target/stm32g4/peripherals/tim_gp.py's GeneralTimer.counter does with the board link's encoder
 * (link.py BoardLink._encoder), operation for operation; every other access, and that one when the angle is not
 * finite or out of range, goes to the board's decoder (the Python models). The timer's state is pushed here by the
 * Python model after each of its stores, the encoder's by the link once a period. Built on first use by
 * src/pmsm_hil/sim_target/stm32g4/periph_native.py. */
#include <math.h>
#include <stdint.h>

#include "periph_ops.h"

typedef uint64_t (*hil_mmio_read_fn)(void *uc, uint64_t offset, unsigned size, void *user);
typedef void (*hil_mmio_write_fn)(void *uc, uint64_t offset, unsigned size, uint64_t value, void *user);

#define LIMIT 2305843009213693952.0 /* 2^61: counts and anchors beyond it are left to Python's integers */

typedef struct {
    /* the timer (GeneralTimer's, pushed after each store): served only while armed */
    int32_t armed;         /* the encoder below is set and the timer's state fits */
    int32_t enc;           /* SMCR.SMS: 1-3 an encoder mode, 0 none */
    int32_t running;       /* CR1.CEN */
    int32_t down;          /* the direction of the last change of the edge count (CR1.DIR) */
    int64_t anchor;        /* encoder counts at which CNT was anchor_cnt */
    int64_t anchor_cnt;
    int64_t modulus;       /* ARR[15:0] + 1 */
    int64_t last_edges;    /* the edge count at the last read */
    uint32_t cnt_offset;   /* CNT's offset in the page */
    int32_t pad;
    /* the encoder (the board link's, once a period) */
    double theta_m;        /* unwrapped mechanical angle at period_start [rad] */
    double omega_m;        /* [rad/s] */
    int64_t period_start;  /* [cycles] */
    double hclk_hz;
    double lines;          /* the encoder's lines per revolution */
    const uint64_t *count; /* the core's cycle count */
    hil_mmio_read_fn fallback_read;
    hil_mmio_write_fn fallback_write;
    void *fallback_user;
} hil_tim_gp_t;

static int64_t floordiv2(int64_t a) { return a >= 0 ? a / 2 : -((-a + 1) / 2); }

static int64_t floormod(int64_t a, int64_t m) {
    int64_t r = a % m;
    return (r != 0 && ((r < 0) != (m < 0))) ? r + m : r;
}

/* GeneralTimer.counter in an encoder mode at cycle `now`: 1 with *out the count, 0 when Python must answer */
static int encoder_count(hil_tim_gp_t *t, int64_t now, uint32_t *out) {
    const double dt = (double)(now - t->period_start) / t->hclk_hz;
    const double theta = t->theta_m + t->omega_m * dt;
    const double x = floor(theta / (2.0 * 3.141592653589793) * 4.0 * t->lines);
    int64_t edges, counts;
    if (!(x > -LIMIT && x < LIMIT)) { /* NaN, infinite or huge: Python raises or computes it with big integers */
        return 0;
    }
    edges = (int64_t)x;
    if (edges != t->last_edges) {
        t->down = edges < t->last_edges;
        t->last_edges = edges;
    }
    if (!t->running) {
        *out = (uint32_t)t->anchor_cnt;
        return 1;
    }
    counts = t->enc == 3 ? edges : floordiv2(edges);
    *out = (uint32_t)floormod(t->anchor_cnt + counts - t->anchor, t->modulus);
    return 1;
}

uint64_t hil_tim_gp_mmio_read(void *uc, uint64_t offset, unsigned size, void *user) {
    hil_tim_gp_t *t = (hil_tim_gp_t *)user;
    uint32_t value;
    if (t->armed && t->enc && offset == t->cnt_offset && size == 4u
        && encoder_count(t, (int64_t)*t->count, &value)) {
        return value;
    }
    return t->fallback_read(uc, offset, size, t->fallback_user);
}

void hil_tim_gp_mmio_write(void *uc, uint64_t offset, unsigned size, uint64_t value, void *user) {
    hil_tim_gp_t *t = (hil_tim_gp_t *)user;
    t->fallback_write(uc, offset, size, value, t->fallback_user);
}

unsigned hil_tim_gp_size(void) { return (unsigned)sizeof(hil_tim_gp_t); }
