/* The virtual board's instruction counter: a Unicorn block hook (UC_HOOK_BLOCK) that adds the Thumb
 * instructions of each block about to execute to a running count, and stops the CPU at the first block that
 * begins at or after the slice's limit (a block begun before it runs whole) (the next peripheral event). Blocks are decoded from the memory the board maps (flash, SRAM,
 * CCM-SRAM), whose host addresses the board hands in; a halfword whose top five bits are 0b11101, 0b11110 or
 * 0b11111 starts a 32-bit instruction (Armv7-M ARM A5.1). A block of the first `n_fixed` regions (the flash and
 * its alias: code the core cannot change) is decoded once: its count is kept in a direct-mapped table by address
 * and size, emptied by the board whenever it writes those regions (ELF loading). Built on first use
 * (src/pmsm_hil/sim_target/stm32g4/counter.py). */
#include <stdint.h>
#include <stddef.h>

#define HIL_COUNTER_REGIONS 6
#define HIL_COUNTER_CACHE 1024 /* a power of two */

typedef struct {
    uint64_t count;                 /* instructions begun so far */
    uint64_t limit;                 /* stop once count >= limit */
    int (*stop)(void *uc);          /* uc_emu_stop */
    uint32_t n_regions;
    uint32_t base[HIL_COUNTER_REGIONS];
    uint32_t size[HIL_COUNTER_REGIONS];
    const uint8_t *host[HIL_COUNTER_REGIONS];
    uint64_t unknown_blocks;        /* blocks outside every region (counted as one instruction per halfword) */
    uint32_t n_fixed;               /* regions [0, n_fixed) hold code that does not change while running: cached */
    uint32_t pad;
    uint32_t cache_address[HIL_COUNTER_CACHE];
    uint32_t cache_size[HIL_COUNTER_CACHE];   /* 0: empty */
    uint32_t cache_count[HIL_COUNTER_CACHE];
    /* the TLB fill (Cpu.VIRTUAL_TLB): the SRAMs, and whether they are executable yet (Cpu.ram_exec) */
    const int32_t *ram_exec;
    uint32_t ram_base[2];
    uint32_t ram_span[2];
} hil_counter_t;

typedef struct {
    uint64_t paddr;
    uint32_t perms;  /* UC_PROT_READ 1, UC_PROT_WRITE 2, UC_PROT_EXEC 4 */
} hil_tlb_entry_t;

#define HIL_MEM_FETCH 18
#define HIL_MEM_FETCH_UNMAPPED 21

static uint32_t block_instructions(hil_counter_t *c, uint64_t address, uint32_t size) {
    uint32_t slot = (uint32_t)(address >> 1) & (HIL_COUNTER_CACHE - 1u);
    if (c->cache_size[slot] == size && size != 0 && c->cache_address[slot] == address) {
        return c->cache_count[slot];
    }
    for (uint32_t r = 0; r < c->n_regions; ++r) {
        if (address >= c->base[r] && address + size <= (uint64_t)c->base[r] + c->size[r]) {
            const uint8_t *p = c->host[r] + (address - c->base[r]);
            uint32_t n = 0;
            uint32_t pos = 0;
            while (pos < size) {
                uint32_t top = (uint32_t)p[pos + 1] >> 3;
                pos += (top == 0x1D || top == 0x1E || top == 0x1F) ? 4u : 2u;
                ++n;
            }
            if (r < c->n_fixed && n != 0) {
                c->cache_address[slot] = (uint32_t)address;
                c->cache_size[slot] = size;
                c->cache_count[slot] = n;
            }
            return n;
        }
    }
    return 0;
}

void hil_counter_block(void *uc, uint64_t address, uint32_t size, void *user) {
    hil_counter_t *c = (hil_counter_t *)user;
    if (c->count >= c->limit) { /* the stop keeps this block from executing: it is not counted */
        c->stop(uc);
        return;
    }
    uint32_t n = block_instructions(c, address, size);
    if (n == 0) {
        n = size / 2u ? size / 2u : 1u;
        ++c->unknown_blocks;
    }
    c->count += n;
}

/* Unicorn's TLB fill in its virtual-TLB mode (UC_HOOK_TLB_FILL; Cpu.VIRTUAL_TLB): the page at `vaddr` maps to itself,
 * readable and writable, executable as the Armv7-M default memory map says (B3.1: the peripheral, device and system
 * regions are execute-never), as the CPU's own fill with the MPU off. A fetch from an execute-never page is refused
 * (Unicorn stops with UC_ERR_EXCEPTION: the board takes it for the prefetch abort the CPU's fill raises; the
 * exception-return addresses at the top never get here). A data access to the SRAMs while no code ran there gets no
 * execute right: Unicorn then clears the page's slow-store flag at its first store (with it, every store takes the
 * slow path). */
int hil_counter_tlb_fill(void *uc, uint64_t vaddr, int type, hil_tlb_entry_t *e, void *user) {
    const hil_counter_t *c = (const hil_counter_t *)user;
    (void)uc;
    int xn = (vaddr >= 0x40000000u && vaddr < 0x60000000u) || vaddr >= 0xA0000000u;
    int fetch = type == HIL_MEM_FETCH || type == HIL_MEM_FETCH_UNMAPPED;
    e->paddr = vaddr;
    if (fetch) {
        e->perms = 7u;
        return !(xn && vaddr < 0xFFFFFC00u);
    }
    int in_ram = 0;
    for (int i = 0; i < 2; ++i) {
        in_ram |= vaddr >= c->ram_base[i] && vaddr - c->ram_base[i] < c->ram_span[i];
    }
    e->perms = 3u | ((xn || (in_ram && !*c->ram_exec)) ? 0u : 4u);
    return 1;
}
