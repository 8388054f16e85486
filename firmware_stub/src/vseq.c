/* Reference firmware: symmetric vector sequences, zero-vector choice, packing, dead-time compensation. */
#include "hil_fw_inverter.h"
#include "hil_fw_vseq.h"

void hil_fw_vseq_nest(hil_fw_vseq_t *q, const uint8_t *states, const uint32_t *times_ns, uint8_t n)
{
    uint8_t st[3];
    uint32_t t[3];
    uint32_t spare = 0u;
    uint8_t m = 0u;
    uint8_t i;
    for (i = 0u; i < n && i < 3u; ++i) {
        if (times_ns[i] > 0u) {
            st[m] = states[i];
            t[m] = times_ns[i];
            ++m;
        }
    }
    /* Outer states too short to halve go to the innermost one (keeps the sum). */
    while (m > 1u && t[0] < 2u) {
        spare += t[0];
        for (i = 1u; i < m; ++i) {
            st[i - 1u] = st[i];
            t[i - 1u] = t[i];
        }
        --m;
    }
    if (m > 2u && t[1] < 2u) {
        spare += t[1];
        st[1] = st[2];
        t[1] = t[2];
        --m;
    }
    q->nest = m;
    q->n = m > 0u ? (uint8_t)(2u * m - 1u) : 0u;
    if (m == 0u) {
        return;
    }
    t[m - 1u] += spare;
    for (i = 0u; i + 1u < m; ++i) {
        const uint32_t first = t[i] / 2u;
        q->states[i] = st[i];
        q->states[q->n - 1u - i] = st[i];
        q->durations_ns[i] = first;
        q->durations_ns[q->n - 1u - i] = t[i] - first;
    }
    q->states[m - 1u] = st[m - 1u];
    q->durations_ns[m - 1u] = t[m - 1u];
}

uint8_t hil_fw_vseq_pack(const hil_fw_vseq_t *q, uint8_t fold, uint8_t odd, uint8_t max_slots, uint8_t *states,
                         uint32_t *durations_ns)
{
    uint8_t i;
    if (!fold) {
        if (q->n > max_slots) {
            return 0u;
        }
        for (i = 0u; i < q->n; ++i) {
            states[i] = q->states[i];
            durations_ns[i] = q->durations_ns[i];
        }
        return q->n;
    }
    if (q->nest > max_slots) {
        return 0u;
    }
    for (i = 0u; i < q->nest; ++i) {
        const uint8_t k = odd ? (uint8_t)(q->nest - 1u - i) : i; /* index into the first half */
        const uint8_t mirror = (uint8_t)(q->n - 1u - k);
        states[i] = q->states[k];
        durations_ns[i] = q->durations_ns[k] + (mirror != k ? q->durations_ns[mirror] : 0u);
    }
    return q->nest;
}

uint8_t hil_fw_vseq_pack_mirror(const hil_fw_vseq_t *q, uint8_t max_slots, uint8_t *states, uint32_t *durations_ns)
{
    uint32_t total = 0u;
    uint32_t outer = 0u;
    uint8_t i;
    if (q->nest == 0u || q->nest > max_slots) {
        return 0u;
    }
    for (i = 0u; i < q->n; ++i) {
        total += q->durations_ns[i];
    }
    for (i = 0u; i + 1u < q->nest; ++i) {
        states[i] = q->states[i];
        durations_ns[i] = q->durations_ns[i]; /* first half: the smaller one when odd */
        outer += q->durations_ns[i];
    }
    states[q->nest - 1u] = q->states[q->nest - 1u];
    durations_ns[q->nest - 1u] = total - 2u * outer;
    return q->nest;
}

uint8_t hil_fw_vseq_expand(const uint8_t *states, const uint32_t *durations_ns, uint8_t n, uint8_t mirror,
                           uint8_t *out_states, uint32_t *out_durations_ns)
{
    uint8_t i;
    for (i = 0u; i < n; ++i) {
        out_states[i] = states[i];
        out_durations_ns[i] = durations_ns[i];
    }
    if (!mirror || n < 2u) {
        return n;
    }
    for (i = 0u; i + 1u < n; ++i) {
        out_states[n + i] = states[n - 2u - i];
        out_durations_ns[n + i] = durations_ns[n - 2u - i];
    }
    return (uint8_t)(2u * n - 1u);
}

uint8_t hil_fw_vseq_transitions(uint8_t prev_code, const uint8_t *states, uint8_t n)
{
    uint8_t total = 0u;
    uint8_t prev = prev_code;
    uint8_t i;
    for (i = 0u; i < n; ++i) {
        total = (uint8_t)(total + hil_fw_leg_transitions(prev, states[i]));
        prev = states[i];
    }
    return total;
}

/* The zero vector one leg away from an active code (weight 1: 000, weight 2: 111). */
static uint8_t zero_adjacent(uint8_t code)
{
    return hil_fw_leg_transitions(code, 0u) <= 1u ? 0u : 7u;
}

/* Transitions of the form actually sent (folded or not), boundary included. */
static uint8_t score(const hil_fw_vseq_t *q, uint8_t prev_code, uint8_t fold, uint8_t odd)
{
    uint8_t st[HIL_FW_VSEQ_MAX];
    uint32_t du[HIL_FW_VSEQ_MAX];
    const uint8_t n = hil_fw_vseq_pack(q, fold, odd, HIL_FW_VSEQ_MAX, st, du);
    return hil_fw_vseq_transitions(prev_code, st, n);
}

void hil_fw_vseq_plan(hil_fw_vseq_t *q, const hil_fw_dwell_t *d, uint8_t zero_select, uint8_t prev_code,
                      uint8_t fold, uint8_t odd)
{
    /* cand[0]: the paper's rule; cand[1]: the alternative (other zero or other nesting). */
    uint8_t st[2][3];
    uint32_t tm[2][3];
    uint8_t n = 0u;
    uint8_t n_cand = 2u;
    const uint8_t z = zero_adjacent(d->v_long);
    const uint8_t has_z = d->t_zero_ns > 0u;
    const uint8_t has_l = d->t_long_ns > 0u;
    const uint8_t has_s = d->t_short_ns > 0u;
    hil_fw_vseq_t alt;
    if (has_z && has_l && has_s) {
        /* Z adjacent to the longer vector outside, the shorter in the middle; or the other zero
         * (adjacent to the shorter vector) with the nesting swapped. */
        st[0][0] = z;            tm[0][0] = d->t_zero_ns;
        st[0][1] = d->v_long;    tm[0][1] = d->t_long_ns;
        st[0][2] = d->v_short;   tm[0][2] = d->t_short_ns;
        st[1][0] = (uint8_t)(7u - z); tm[1][0] = d->t_zero_ns;
        st[1][1] = d->v_short;   tm[1][1] = d->t_short_ns;
        st[1][2] = d->v_long;    tm[1][2] = d->t_long_ns;
        n = 3u;
    } else if (has_z && (has_l || has_s)) {
        const uint8_t v = has_l ? d->v_long : d->v_short;
        const uint32_t t = has_l ? d->t_long_ns : d->t_short_ns;
        st[0][0] = zero_adjacent(v);               tm[0][0] = d->t_zero_ns;
        st[0][1] = v;                              tm[0][1] = t;
        st[1][0] = (uint8_t)(7u - zero_adjacent(v)); tm[1][0] = d->t_zero_ns;
        st[1][1] = v;                              tm[1][1] = t;
        n = 2u;
    } else if (has_l && has_s) {
        st[0][0] = d->v_long;  tm[0][0] = d->t_long_ns;
        st[0][1] = d->v_short; tm[0][1] = d->t_short_ns;
        st[1][0] = d->v_short; tm[1][0] = d->t_short_ns;
        st[1][1] = d->v_long;  tm[1][1] = d->t_long_ns;
        n = 2u;
    } else if (has_z) {
        st[0][0] = z;                tm[0][0] = d->t_zero_ns;
        st[1][0] = (uint8_t)(7u - z); tm[1][0] = d->t_zero_ns;
        n = 1u;
    } else {
        st[0][0] = has_l ? d->v_long : d->v_short;
        tm[0][0] = has_l ? d->t_long_ns : d->t_short_ns;
        n = 1u;
        n_cand = 1u;
    }
    hil_fw_vseq_nest(q, st[0], tm[0], n);
    if (zero_select == HIL_FW_ZERO_MIN_TRANSITIONS && n_cand > 1u) {
        hil_fw_vseq_nest(&alt, st[1], tm[1], n);
        if (score(&alt, prev_code, fold, odd) < score(q, prev_code, fold, odd)) {
            *q = alt;
        }
    }
}

uint8_t hil_fw_vseq_dt_comp(const uint8_t *states, uint32_t *durations_ns, uint8_t n, const float *i_abc,
                            uint32_t t_dead_ns)
{
    uint8_t moved = 0u;
    uint8_t j;
    for (j = 0u; j + 1u < n; ++j) {
        const uint8_t flips = (uint8_t)((states[j] ^ states[j + 1u]) & 7u);
        uint8_t delayed = 0u;
        uint8_t legs = 0u;
        uint8_t leg;
        for (leg = 0u; leg < 3u; ++leg) {
            const uint8_t bit = (uint8_t)(2u - leg); /* leg a is the MSB */
            if ((flips >> bit) & 1u) {
                const uint8_t rising = (uint8_t)((states[j + 1u] >> bit) & 1u);
                ++legs;
                if ((rising && i_abc[leg] > 0.0f) || (!rising && i_abc[leg] < 0.0f)) {
                    ++delayed;
                }
            }
        }
        /* An edge moves only when every leg switching on it is delayed (else it would split). */
        if (legs > 0u && delayed == legs) {
            const uint32_t shift = durations_ns[j] < t_dead_ns ? durations_ns[j] : t_dead_ns;
            durations_ns[j] -= shift;
            durations_ns[j + 1u] += shift;
            moved = (uint8_t)(moved + (shift > 0u ? 1u : 0u));
        }
    }
    return moved;
}

uint8_t hil_fw_vseq_dt_comp_mirror(const uint8_t *states, uint32_t *durations_ns, uint8_t n, const float *i_abc,
                                   uint32_t t_dead_ns)
{
    /* Edge j (between slots j and j+1) sits at e_j = d0 + .. + dj in the first half and at
     * total - e_j in the second; the innermost slot is total - 2 e_(n-2). */
    int32_t e[HIL_FW_VSEQ_MAX];
    int32_t total = 0;
    int32_t prev = 0;
    const int32_t half_td = (int32_t)(t_dead_ns / 2u);
    uint8_t moved = 0u;
    uint8_t j;
    if (n < 2u || n > HIL_FW_VSEQ_MAX) {
        return 0u;
    }
    for (j = 0u; j + 1u < n; ++j) {
        total += 2 * (int32_t)durations_ns[j];
        e[j] = (j > 0u ? e[j - 1u] : 0) + (int32_t)durations_ns[j];
    }
    total += (int32_t)durations_ns[n - 1u];
    for (j = 0u; j + 1u < n; ++j) {
        const uint8_t flips = (uint8_t)((states[j] ^ states[j + 1u]) & 7u);
        int32_t dir = 0; /* -1 earlier, +1 later */
        uint8_t agree = flips != 0u;
        uint8_t leg;
        int32_t hi;
        int32_t target;
        for (leg = 0u; leg < 3u && agree; ++leg) {
            const uint8_t bit = (uint8_t)(2u - leg); /* leg a is the MSB */
            if ((flips >> bit) & 1u) {
                const int32_t rising = (int32_t)((states[j + 1u] >> bit) & 1u);
                const int32_t sgn = i_abc[leg] > 0.0f ? 1 : (i_abc[leg] < 0.0f ? -1 : 0);
                /* the leg's high time grows by sgn*t_dead: inner pulse high (rising inward) ->
                 * edge earlier for sgn > 0; inner pulse low (falling inward) -> edge later */
                const int32_t want = rising ? -sgn : sgn;
                if (want == 0 || (dir != 0 && want != dir)) {
                    agree = 0u;
                }
                dir = want;
            }
        }
        target = e[j] + (agree ? dir * half_td : 0);
        hi = j + 2u < n ? e[j + 1u] : total / 2; /* not past the next edge / the middle */
        target = target < prev ? prev : (target > hi ? hi : target);
        moved = (uint8_t)(moved + (target != e[j] ? 1u : 0u));
        e[j] = target;
        prev = target;
    }
    for (j = 0u; j + 1u < n; ++j) {
        durations_ns[j] = (uint32_t)(e[j] - (j > 0u ? e[j - 1u] : 0));
    }
    durations_ns[n - 1u] = (uint32_t)(total - 2 * e[n - 2u]);
    return moved;
}
