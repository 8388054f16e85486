/*
 * Reference firmware: three-vector MPC (3vmpc), the benchmark of 003_7bbad73a6f78337e.txt: every
 * period two adjacent active vectors and a zero vector with eq. (9) dwell times, chosen by
 * searching all six adjacent pairs, applied as the symmetric sequence. See docs/algorithms/hv_mpfc.md.
 */
#include "hil_fw_3vmpc.h"
#include "hil_fw_hv_mpfc.h"
#include "hil_fw_state.h"

void hil_fw_3vmpc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    hil_fw_hv_problem_t p;
    hil_fw_hv_pair_t pair;
    hil_fw_hv_pair_t best;
    hil_fw_dwell_t dwell;
    uint8_t start;
    uint8_t sector;
    uint8_t requested;
    uint8_t mode;
    uint8_t j;
    hil_fw_hv_prepare(s, &p);
    /* Search all six adjacent pairs (one prediction each), starting from the flux-error sector
     * so that ties keep it; the pair leaving the smallest flux error wins. */
    start = hil_fw_hv_sector(p.err_alpha, p.err_beta);
    sector = start;
    hil_fw_hv_pair_duties(&p, start, s->params.model.ts, &best);
    for (j = 1u; j < 6u; ++j) {
        const uint8_t sec = (uint8_t)((start - 1u + j) % 6u + 1u);
        hil_fw_hv_pair_duties(&p, sec, s->params.model.ts, &pair);
        if (pair.err2 < best.err2) {
            best = pair;
            sector = sec;
        }
    }
    /* Always three vectors (t_thr = 0): zero-length vectors are simply left out. */
    mode = hil_fw_hv_modes(&p, &best, 0.0f, s->params.model.ts_ns, &dwell, &requested);
    hil_fw_hv_emit(s, &p, &dwell, cmd);
    hil_fw_hv_finish(s, &p, &best, sector, mode, requested, cmd);
    cmd->candidates = HIL_FW_3VMPC_CANDIDATES;
}
