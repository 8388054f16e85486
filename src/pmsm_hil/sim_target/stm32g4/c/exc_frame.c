/* The virtual board's exception entry and return frames in C (Armv7-M B1.5.6-B1.5.8), the same steps as the
 * Python reference (src/pmsm_hil/sim_target/stm32g4/exceptions.py) in one call each instead of several calls into
 * Unicorn: entry reads CONTROL, PSP, MSP and the basic frame's registers (and the FP context), stacks the frame
 * (8 or 26 words, 8-byte aligned with CCR.STKALIGN), reads the vector and writes CONTROL, the stack pointer, LR =
 * EXC_RETURN, xPSR and PC; return pops the frame EXC_RETURN names and restores the registers. The NVIC's state and
 * the cycle costs stay with the caller. Unicorn's functions are handed in (this library does not link Unicorn).
 * Built on first use (src/pmsm_hil/sim_target/stm32g4/exc_native.py). */
#include <stdint.h>
#include <string.h>

typedef int (*hil_reg_batch_fn)(void *uc, const int *regs, void **vals, int count);
typedef int (*hil_mem_read_fn)(void *uc, uint64_t address, void *bytes, uint64_t size);
typedef int (*hil_mem_write_fn)(void *uc, uint64_t address, const void *bytes, uint64_t size);

typedef struct {
    void *uc;
    hil_reg_batch_fn reg_read_batch;
    hil_reg_batch_fn reg_write_batch;
    hil_mem_read_fn mem_read;
    hil_mem_write_fn mem_write;
    int reg_control, reg_psp, reg_msp, reg_lr, reg_xpsr, reg_pc;
    int frame_regs[8];  /* r0-r3, r12, lr, pc, xpsr */
    int fp_regs[17];    /* s0-s15, fpscr */
} hil_exc_t;

#define BASIC_WORDS 8u
#define EXTENDED_WORDS 26u

static int read_regs(const hil_exc_t *x, const int *ids, uint32_t *values, int count) {
    void *ptrs[32];
    for (int i = 0; i < count; ++i) {
        ptrs[i] = &values[i];
    }
    return x->reg_read_batch(x->uc, ids, ptrs, count);
}

static int write_regs(const hil_exc_t *x, const int *ids, uint32_t *values, int count) {
    void *ptrs[32];
    for (int i = 0; i < count; ++i) {
        ptrs[i] = &values[i];
    }
    return x->reg_write_batch(x->uc, ids, ptrs, count);
}

/* Take an exception: `in_thread` (nothing active), `fp` (CPACR grants CP10/11), `ccr`, `ipsr` (the active
 * exception, 0 in Thread mode), the vector at `vector_address`. Returns Unicorn's error (0 on success). */
int hil_exc_enter(const hil_exc_t *x, int in_thread, int fp, uint32_t ccr, uint32_t ipsr, uint32_t vector_address) {
    int ids[11] = {x->reg_control, x->reg_psp, x->reg_msp};
    memcpy(&ids[3], x->frame_regs, sizeof x->frame_regs);
    uint32_t state[11];
    int err = read_regs(x, ids, state, 11);
    if (err) {
        return err;
    }
    uint32_t control = state[0], psp = state[1], msp = state[2];
    uint32_t frame[EXTENDED_WORDS];
    memcpy(frame, &state[3], BASIC_WORDS * 4u);
    int use_psp = in_thread && (control & 2u);
    uint32_t sp = use_psp ? psp : msp;
    uint32_t size = (fp ? EXTENDED_WORDS : BASIC_WORDS) * 4u;
    int aligned = (ccr & 0x200u) && (sp & 4u);
    uint32_t frame_sp = (ccr & 0x200u) ? ((sp - size) & ~4u) : sp - size;
    frame[7] = (frame[7] & ~0x1FFu & ~(1u << 9)) | ipsr | (aligned ? 1u << 9 : 0u) | (1u << 24);
    if (fp) {
        err = read_regs(x, x->fp_regs, &frame[8], 17);
        if (err) {
            return err;
        }
        frame[25] = 0u;
    }
    err = x->mem_write(x->uc, frame_sp, frame, size);
    if (err) {
        return err;
    }
    uint32_t exc_return = fp ? 0xFFFFFFE1u : 0xFFFFFFF1u;
    if (in_thread) {
        exc_return |= use_psp ? 0xCu : 0x8u;
    }
    uint32_t handler;
    err = x->mem_read(x->uc, vector_address, &handler, 4u);
    if (err) {
        return err;
    }
    int out_ids[5] = {x->reg_control, use_psp ? x->reg_psp : x->reg_msp, x->reg_lr, x->reg_xpsr, x->reg_pc};
    uint32_t out[5] = {use_psp ? control & ~2u & ~4u : control & ~4u, frame_sp, exc_return, 1u << 24,
                       handler & ~1u};
    return write_regs(x, out_ids, out, 5);
}

/* Return from the active exception: `use_psp` (EXC_RETURN bit 2), `fp` (bit 4 clear). Returns Unicorn's error. */
int hil_exc_leave(const hil_exc_t *x, int use_psp, int fp) {
    int ids[3] = {x->reg_control, x->reg_psp, x->reg_msp};
    uint32_t state[3];
    int err = read_regs(x, ids, state, 3);
    if (err) {
        return err;
    }
    uint32_t control = state[0];
    uint32_t sp = use_psp ? state[1] : state[2];
    uint32_t size = (fp ? EXTENDED_WORDS : BASIC_WORDS) * 4u;
    uint32_t frame[EXTENDED_WORDS];
    err = x->mem_read(x->uc, sp, frame, size);
    if (err) {
        return err;
    }
    uint32_t xpsr = frame[7];
    uint32_t new_sp = sp + size + ((xpsr & (1u << 9)) ? 4u : 0u);
    control = use_psp ? (control | 2u) : (control & ~2u);
    control = fp ? (control | 4u) : (control & ~4u);
    int head_ids[8] = {x->reg_control, use_psp ? x->reg_psp : x->reg_msp};
    memcpy(&head_ids[2], x->frame_regs, 6 * sizeof(int));
    uint32_t head[8] = {control, new_sp};
    memcpy(&head[2], frame, 6u * 4u);
    err = write_regs(x, head_ids, head, 8);
    if (err) {
        return err;
    }
    if (fp) {
        err = write_regs(x, x->fp_regs, &frame[8], 17);
        if (err) {
            return err;
        }
    }
    int tail_ids[2] = {x->reg_xpsr, x->reg_pc};
    uint32_t tail[2] = {xpsr & ~0x1FFu & ~(1u << 9), frame[6] & ~1u};
    return write_regs(x, tail_ids, tail, 2);
}

/* The DWT page's reads (0xE0001000) as Unicorn's MMIO read callback, registered by uc_mmio_map straight (no Python
 * frame per access): CTRL, CYCCNT (the core's cycle count since its anchor while CYCCNTENA, else the frozen value),
 * the profiling counters, comparators and ID registers as 0; any other offset goes to `fallback` (the Python
 * reference, which names the unmodelled register). The state mirrors SystemControl's, written back by the board
 * after every DWT write (src/pmsm_hil/sim_target/stm32g4/scs.py, dwt_read). */
typedef uint64_t (*hil_mmio_read_fn)(void *uc, uint64_t offset, unsigned size, void *user);

typedef struct {
    const uint64_t *count;  /* the instruction counter's running count: the core's cycles */
    int64_t cyccnt_base;    /* cycle at which CYCCNT was 0 */
    uint32_t ctrl;
    uint32_t cyccnt_frozen; /* CYCCNT while not counting */
    hil_mmio_read_fn fallback;
    void *fallback_user;
} hil_dwt_t;

uint64_t hil_dwt_read(void *uc, uint64_t offset, unsigned size, void *user) {
    const hil_dwt_t *d = (const hil_dwt_t *)user;
    if (offset == 0x000u) {
        return d->ctrl;
    }
    if (offset == 0x004u) {
        return (d->ctrl & 1u) ? (uint32_t)(*d->count - (uint64_t)d->cyccnt_base) : d->cyccnt_frozen;
    }
    if (offset >= 0xFD0u || (offset >= 0x008u && offset < 0x100u)) {
        return 0u;
    }
    return d->fallback(uc, offset, size, d->fallback_user);
}
