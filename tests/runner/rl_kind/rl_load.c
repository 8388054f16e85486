/*
 * A trivial machine kind for the recipe test (docs/recipes.md, "A new machine kind"): a balanced three-phase
 * R-L load in star (isolated neutral, no back-EMF) on a two-level inverter, solved exactly per sub-interval:
 * in the stationary alpha-beta frame each axis is i' = (v - R i) / L with v constant, so
 * i(t + h) = v/R + (i - v/R) exp(-R h / L). The "rotor" angle only turns the dq view of the currents: it
 * advances at the held speed (the load makes no torque; a load torque or inertia has no effect). No dead time.
 * Units: SI (A, V, Ohm, H, rad, rad/s, s), time in ns.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "gate_edges.h"
#include "machine_kernel.h"
#include "mechanics.h"

#define RL_TRACE_COLUMNS 6 /* t [s], i_a, i_b, i_c [A], torque [N*m], omega_m [rad/s] */

typedef struct {
    double r;           /* phase resistance [Ohm] */
    double l;           /* phase inductance [H] */
    double vdc;         /* DC link [V] */
    mech_params_t mech; /* written by PlantBase (mechanics.h); unused: the load makes no torque, its speed stays */
    int32_t pole_pairs; /* turns the dq view: theta_e = pole_pairs * mechanical angle */
} rl_params_t;

typedef struct {
    uint64_t t_ns;      /* plant time [ns] */
    uint64_t trace_k;   /* next trace row index */
    double i_al, i_be;  /* stationary-frame currents [A] */
    double theta_e;     /* [rad] */
    mech_state_t mech;  /* the shaft's speed [rad/s] (mechanics.h) */
    int32_t gate;       /* applied gate code */
} rl_state_t;

typedef ge_period_stats_t rl_period_stats_t;


#define RL_SQRT3 1.7320508075688772935274463415059
#define RL_TWO_PI 6.283185307179586476925286766559

/* Phase-to-neutral voltages in alpha-beta of a gate code 4*Sa + 2*Sb + Sc [V] (amplitude invariant). */
static void code_voltage(double vdc, int32_t code, double *v_al, double *v_be)
{
    const double sa = (double)((code >> 2) & 1);
    const double sb = (double)((code >> 1) & 1);
    const double sc = (double)(code & 1);
    *v_al = vdc * (2.0 * sa - sb - sc) / 3.0;
    *v_be = vdc / RL_SQRT3 * (sb - sc);
}

static void phase_currents(double i_al, double i_be, double *i)
{
    i[0] = i_al;
    i[1] = -0.5 * i_al + 0.5 * RL_SQRT3 * i_be;
    i[2] = -0.5 * i_al - 0.5 * RL_SQRT3 * i_be;
}

/* Exact state after h seconds from (i_al, i_be, theta) under constant voltage. */
static void solve(const rl_params_t *p, const rl_state_t *s, double v_al, double v_be, double h, double *i_al,
                  double *i_be, double *theta)
{
    const double e = exp(-p->r * h / p->l);
    *i_al = v_al / p->r + (s->i_al - v_al / p->r) * e;
    *i_be = v_be / p->r + (s->i_be - v_be / p->r) * e;
    *theta = fmod(s->theta_e + (double)p->pole_pairs * s->mech.omega_m * h, RL_TWO_PI);
}

static int bits(int32_t x)
{
    return (x & 1) + ((x >> 1) & 1) + ((x >> 2) & 1);
}

static int rl_advance(const rl_params_t *p, rl_state_t *s, const int32_t *states, const int64_t *durations_ns, int32_t n,
               const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap, ge_period_stats_t *stats)
{
    int32_t k;
    int32_t rows = 0;
    double peak = 0.0;
    (void)load;
    ge_stats_reset(stats);
    if (n < 1 || n > GE_MAX_SUBINTERVALS) {
        return MK_E_ARGS;
    }
    for (k = 0; k < n; ++k) {
        if (states[k] < 0 || states[k] > 7 || durations_ns[k] < 0) {
            return MK_E_ARGS;
        }
    }
    for (k = 0; k < n; ++k) {
        const uint64_t t0_ns = s->t_ns;
        const uint64_t t1_ns = t0_ns + (uint64_t)durations_ns[k];
        double v_al, v_be;
        const uint32_t edges = (uint32_t)bits(states[k] ^ s->gate);
        stats->leg_transitions += edges;
        if (k == 0) {
            stats->boundary_transitions += edges;
        }
        s->gate = states[k];
        code_voltage(p->vdc, states[k], &v_al, &v_be);
        if (trace_dt > 0.0 && trace != NULL) { /* trace rows at t = trace_k * trace_dt inside [t0, t1) */
            for (;;) {
                const double t_row = (double)s->trace_k * trace_dt;
                double i_al, i_be, th, i[3];
                int j;
                if (t_row >= (double)t1_ns * 1e-9) {
                    break;
                }
                if (rows >= trace_cap) {
                    return MK_E_TRACE_FULL;
                }
                solve(p, s, v_al, v_be, t_row - (double)t0_ns * 1e-9, &i_al, &i_be, &th);
                phase_currents(i_al, i_be, i);
                trace[rows * RL_TRACE_COLUMNS + 0] = t_row;
                for (j = 0; j < 3; ++j) {
                    trace[rows * RL_TRACE_COLUMNS + 1 + j] = i[j];
                    peak = fabs(i[j]) > peak ? fabs(i[j]) : peak;
                }
                trace[rows * RL_TRACE_COLUMNS + 4] = 0.0;
                trace[rows * RL_TRACE_COLUMNS + 5] = s->mech.omega_m;
                rows++;
                s->trace_k++;
            }
        }
        solve(p, s, v_al, v_be, (double)durations_ns[k] * 1e-9, &s->i_al, &s->i_be, &s->theta_e);
        s->t_ns = t1_ns;
    }
    stats->trace_n = rows;
    stats->peak_current = peak;
    return 0;
}

void rl_sample(const rl_params_t *p, const rl_state_t *s, mk_sample_t *out)
{
    const double co = cos(s->theta_e);
    const double sn = sin(s->theta_e);
    (void)p;
    phase_currents(s->i_al, s->i_be, out->i);
    out->i_d = s->i_al * co + s->i_be * sn;
    out->i_q = -s->i_al * sn + s->i_be * co;
    out->theta_e = s->theta_e;
    out->omega_m = s->mech.omega_m;
    out->torque = 0.0;
}

/* the machine-kernel table (machine_kernel.h) */
const mk_kernel_t *rl_kernel(void);
MK_KERNEL_TABLE(rl, rl_params_t, rl_state_t, rl_advance, rl_sample, "three-phase R-L load", 3, 7, RL_TRACE_COLUMNS)
