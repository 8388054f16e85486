/* The drive's mechanics shared by every machine kernel; see mechanics.h. */
#include "mechanics.h"

#include <stddef.h>

/* One mass: trapezoidal torque, implicit friction: (1 + k) w1 = (1 - k) w0 + piece (Te - Tl) / J. */
static void step_one_mass(const mech_params_t *p, mech_state_t *s, double piece, double te0, double te1,
                          double t_load)
{
    const double inv_j = 1.0 / p->j; /* [1/(kg*m^2)] */
    const double k = 0.5 * piece * p->b * inv_j;
    const double w1 = s->omega_m * (1.0 - k) + piece * (0.5 * (te0 + te1) - t_load) * inv_j;
    s->omega_m = k != 0.0 ? w1 / (1.0 + k) : w1;
}

/* Solve the 3x3 system m x = r in place (Gaussian elimination with partial pivoting); x in r. */
static void solve3(double m[3][3], double r[3])
{
    for (int c = 0; c < 3; c++) {
        int piv = c;
        for (int i = c + 1; i < 3; i++) {
            if ((m[i][c] < 0.0 ? -m[i][c] : m[i][c]) > (m[piv][c] < 0.0 ? -m[piv][c] : m[piv][c])) {
                piv = i;
            }
        }
        if (piv != c) {
            for (int k = 0; k < 3; k++) {
                const double t = m[c][k];
                m[c][k] = m[piv][k];
                m[piv][k] = t;
            }
            {
                const double t = r[c];
                r[c] = r[piv];
                r[piv] = t;
            }
        }
        for (int i = c + 1; i < 3; i++) {
            const double f = m[i][c] / m[c][c];
            for (int k = c; k < 3; k++) {
                m[i][k] -= f * m[c][k];
            }
            r[i] -= f * r[c];
        }
    }
    for (int c = 2; c >= 0; c--) {
        double acc = r[c];
        for (int k = c + 1; k < 3; k++) {
            acc -= m[c][k] * r[k];
        }
        r[c] = acc / m[c][c];
    }
}

/* Two masses on an elastic shaft, x = (w, w_l, tw), x' = A x + u: the trapezoidal rule
 * (I - piece/2 A) x1 = (I + piece/2 A) x0 + piece u, with the air-gap torque averaged over the piece. */
static void step_two_mass(const mech_params_t *p, mech_state_t *s, double piece, double te0, double te1,
                          double t_load)
{
    const double j1 = p->j, j2 = p->j_load, kk = p->k_shaft, cc = p->c_shaft;
    const double a[3][3] = {
        {-(p->b + cc) / j1, cc / j1, -kk / j1},
        {cc / j2, -cc / j2, kk / j2},
        {1.0, -1.0, 0.0},
    };
    const double u[3] = {0.5 * (te0 + te1) / j1, -t_load / j2, 0.0};
    const double x0[3] = {s->omega_m, s->omega_l, s->twist};
    double m[3][3], r[3];
    for (int i = 0; i < 3; i++) {
        r[i] = x0[i] + piece * u[i];
        for (int k = 0; k < 3; k++) {
            r[i] += 0.5 * piece * a[i][k] * x0[k];
            m[i][k] = (i == k ? 1.0 : 0.0) - 0.5 * piece * a[i][k];
        }
    }
    solve3(m, r);
    s->omega_m = r[0];
    s->omega_l = r[1];
    s->twist = r[2];
}

/* mech_step, inline in mech_integrate's piece loop */
static inline void step(const mech_params_t *p, mech_state_t *s, double piece, double te0, double te1, double t_load)
{
    if (p->mode == MECH_INERTIA) {
        step_one_mass(p, s, piece, te0, te1, t_load);
    } else if (p->mode == MECH_TWO_MASS) {
        step_two_mass(p, s, piece, te0, te1, t_load);
    }
}

void mech_step(const mech_params_t *p, mech_state_t *s, double piece, double te0, double te1, double t_load)
{
    step(p, s, piece, te0, te1, t_load);
}

int mech_integrate(const mech_params_t *p, mech_state_t *s, const mech_segment_t *load, double t_abs, double h,
                   mech_piece_fn piece_fn, mech_torque_fn torque_fn, void *ctx)
{
    const int moving = p->mode != MECH_DYNO;
    double done = 0.0;
    while (done < h - 0.5e-9) {
        double piece = h - done;
        const double t0 = t_abs + done;
        double te0 = 0.0;
        int rc;
        if (moving) {
            if (p->max_piece > 0.0 && piece > p->max_piece) {
                piece = p->max_piece;
            }
            te0 = torque_fn(ctx);
        }
        rc = piece_fn(ctx, t0, &piece, s->omega_m);
        if (rc != 0) {
            return rc;
        }
        if (moving) {
            const double t_load = load->value + load->slope * (t0 + 0.5 * piece - load->t_ref);
            step(p, s, piece, te0, torque_fn(ctx), t_load);
        }
        done += piece;
    }
    return 0;
}

void mech_hold(mech_params_t *p, mech_state_t *s, double omega_m)
{
    p->mode = MECH_DYNO;
    s->omega_m = omega_m;
    s->omega_l = omega_m;
    s->twist = 0.0;
}
