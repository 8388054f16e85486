/* The interface between the virtual board's scheduler and a peripheral model written in C (the C twin of
 * peripherals/base.py's Peripheral: next_event / advance, and the NVIC lines a model raises). Times are the board's
 * clock: HCLK cycles since reset (the instruction count, CPI = 1). A model keeps its state in its own fixed-size
 * struct; its registers are served by its own uc_mmio_map callbacks. */
#ifndef HIL_PERIPH_OPS_H
#define HIL_PERIPH_OPS_H

#include <stdint.h>

/* Where a model's interrupt lines go (the NVIC): `irq` is the external interrupt number (0 = WWDG, RM0440 table
 * 97), level-sensitive as on the chip: asserted while the model's flag and enable are both set. */
typedef struct hil_irq_sink {
    void *board;
    void (*assert_line)(void *board, int irq);
    void (*withdraw_line)(void *board, int irq);
    /* a register access reached model `self` through its own MMIO callback (`write`: a store), which the board does
     * not see: the scheduler asks the model (and its event group) again at its next step, and after a store whose
     * model's next event moved before the running slice's end the core stops at its next block */
    void (*touched)(void *board, void *self, int write);
} hil_irq_sink_t;

/* One model as the scheduler sees it. */
typedef struct hil_periph_ops {
    void *self;
    /* the earliest cycle after `now` at which the model changes state by itself; -1: none */
    int64_t (*next_event)(void *self, int64_t now);
    /* bring the model's state up to cycle `now` (what is due at or before `now` takes effect) */
    void (*advance)(void *self, int64_t now);
} hil_periph_ops_t;

/* The `size`-byte lane at byte `offset` of the 32-bit register value `word` (a byte or halfword access). */
static inline uint32_t hil_reg_lane(uint32_t word, unsigned offset, unsigned size) {
    if (size == 4u) {
        return word;
    }
    return (word >> (8u * (offset & 3u))) & ((1u << (8u * size)) - 1u);
}

/* `old` with its `size`-byte lane at byte `offset` replaced by `value` (a byte or halfword write). */
static inline uint32_t hil_reg_merge(uint32_t old, unsigned offset, unsigned size, uint32_t value) {
    if (size == 4u) {
        return value;
    }
    unsigned shift = 8u * (offset & 3u);
    uint32_t mask = ((1u << (8u * size)) - 1u) << shift;
    return (old & ~mask) | ((value << shift) & mask);
}

/* A read a model served itself: reported to the sink's `touched` (a scheduler in C that must know the model was
 * accessed) and the accessed lane of the register's value returned. */
static inline uint64_t hil_served_read(const hil_irq_sink_t *sink, void *self, uint32_t value, unsigned offset,
                                       unsigned size) {
    if (sink->touched) {
        sink->touched(sink->board, self, 0);
    }
    return hil_reg_lane(value, offset, size);
}

#endif
