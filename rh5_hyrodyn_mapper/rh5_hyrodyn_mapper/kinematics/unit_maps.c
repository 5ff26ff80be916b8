/* The joint <-> actuator maths of every RH5 submechanism, in one place: lengths, Jacobian, acceleration bias and
 * condition number at a pose, forward kinematics (closed form or Newton) and the statics, one unit at one sample.
 * The row layout of each kind is in unit_maps.h; _compiled.c runs these over the units and samples of a call. */
#include <math.h>
#include <stddef.h>

#include "unit_maps.h"

#define LEGS 14 /* first leg column of SPU and SPRR rows */
#define ROUNDING 1e-12 /* |cos(phi)| may exceed 1 by this much through rounding before a length is unreachable */

/* The universal joint at y: R(y) = Rx(y0) Ry(y1) in the canonical frame, omega = W y_dot, alpha = W-dot y_dot. */
typedef struct {
    double c0, s0, c1, s1;
    double omega[3], alpha[3];
    int rates;
} Ujoint;

static Ujoint ujoint(const double *y, const double *yd) {
    Ujoint u = {cos(y[0]), sin(y[0]), cos(y[1]), sin(y[1]), {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, yd != NULL};
    if (yd != NULL) {
        double w0 = yd[0], w1 = yd[1];
        u.omega[0] = w0; /* W = [x, Rx(y0) y] = [(1, 0, 0), (0, c0, s0)] */
        u.omega[1] = u.c0 * w1;
        u.omega[2] = u.s0 * w1;
        u.alpha[1] = -u.s0 * w0 * w1; /* alpha = y0d y1d (x cross Rx(y0) y); alpha_x = 0 */
        u.alpha[2] = u.c0 * w0 * w1;
    }
    return u;
}

static void cross(const double *a, const double *b, double *out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* R(y) p0 for a point or direction p0 of the platform at y = 0. */
static void rotate(const Ujoint *u, const double *p0, double *out) {
    double t = u->c1 * p0[2] - u->s1 * p0[0];
    out[0] = u->c1 * p0[0] + u->s1 * p0[2];
    out[1] = u->c0 * p0[1] - u->s0 * t;
    out[2] = u->s0 * p0[1] + u->c0 * t;
}

/* A point's velocity omega x p and acceleration alpha x p + omega x (omega x p) on the platform. */
static void motion(const Ujoint *u, const double *p, double *vel, double *acc) {
    double a[3], q[3];
    cross(u->omega, p, vel);
    cross(u->alpha, p, a);
    cross(u->omega, vel, q);
    for (int i = 0; i < 3; ++i) acc[i] = a[i] + q[i];
}

/* One leg's Jacobian row (design/mechanisms.md 4.3, 5.3): l_dot = (base x point) . omega / l, omega = W y_dot. */
static void leg_row(const Ujoint *u, const double *base, const double *point, double l, double *row) {
    double m[3];
    cross(base, point, m);
    row[0] = m[0] / l;
    row[1] = (u->c0 * m[1] + u->s0 * m[2]) / l;
}

/* 2-SPU+1U leg (section 4): base U joint b, platform S joint e0 at y = 0; l = |R e0 - b|, bias (4.4). */
static void spu_leg(const Ujoint *u, const double *p, double *l, double *row, double *b) {
    double e[3], d[3];
    rotate(u, p + 3, e);
    for (int i = 0; i < 3; ++i) d[i] = e[i] - p[i];
    *l = sqrt(dot(d, d));
    leg_row(u, p, e, *l, row);
    if (u->rates) {
        double v[3], acc[3];
        motion(u, e, v, acc);
        double ndv = dot(d, v) / *l;
        *b = dot(d, acc) / *l + (dot(v, v) - ndv * ndv) / *l;
    }
}

/* 2-SPRR+1U leg (section 5): shank pivot s, crank of radius r about the foot axis (centre f0, direction a0);
 * l = sqrt(alpha^2 + (rho - r)^2) with alpha = a . delta, rho = |delta - alpha a|, delta = s - f (5.2); the rod
 * end k on the crank circle closest to s gives J (5.3); the bias differentiates the scalar identities twice (5.4). */
static void sprr_leg(const Ujoint *u, const double *p, double *l, double *row, double *b) {
    const double *s = p, r = p[9];
    double f[3], a[3], t[3], q[3], k[3];
    rotate(u, p + 3, f);
    rotate(u, p + 6, a);
    for (int i = 0; i < 3; ++i) t[i] = s[i] - f[i];
    double alpha = dot(a, t);
    for (int i = 0; i < 3; ++i) q[i] = t[i] - alpha * a[i];
    double rho = sqrt(dot(q, q)), e = rho - r;
    *l = sqrt(alpha * alpha + e * e);
    double g = r / rho;
    for (int i = 0; i < 3; ++i) k[i] = f[i] + g * q[i];
    leg_row(u, s, k, *l, row);
    if (u->rates) {
        double fv[3], fa[3], av[3], aa[3];
        motion(u, f, fv, fa); /* delta_dot = -f_dot */
        motion(u, a, av, aa);
        double d_dot = -dot(t, fv);                     /* D_dot / 2, D = |delta|^2 */
        double d_ddot = dot(fv, fv) - dot(t, fa);       /* D_ddot / 2 */
        double a_dot = dot(av, t) - dot(a, fv);         /* A = a . delta = alpha */
        double a_ddot = dot(aa, t) - 2.0 * dot(av, fv) - dot(a, fa);
        double rho_dot = (d_dot - alpha * a_dot) / rho;
        double rho_ddot = (d_ddot - a_dot * a_dot - alpha * a_ddot - rho_dot * rho_dot) / rho;
        double l_dot = (d_dot - r * rho_dot) / *l;
        *b = (d_ddot - r * rho_ddot - l_dot * l_dot) / *l;
    }
}

/* l = T x over the non-zero entries of T (row-major m x m), plus ``add`` when given. */
static void matvec(int m, const double *t, const double *x, const double *add, double *out, int transpose) {
    for (int i = 0; i < m; ++i) {
        double sum = 0.0;
        for (int k = 0; k < m; ++k) {
            double tik = transpose ? t[MAX_DOF * k + i] : t[MAX_DOF * i + k];
            if (tik != 0.0) sum += tik * x[k];
        }
        out[i] = add == NULL ? sum : sum + add[i];
    }
}

/* The pose of one unit at joints y; the bias only when yd is given. */
void unit_pose(const double *row, const double *y, const double *yd, Pose *p) {
    switch ((int)row[0]) {
        case KIND_RRPR: { /* section 3: l^2 = k0 - k1 cos(phi), phi = phi0 + q */
            double k1 = row[6], phi = row[4] + y[0], c = cos(phi);
            double l = sqrt(row[5] - k1 * c), j = row[7] * sin(phi) / l;
            p->l[0] = l;
            p->j[0] = j;
            if (yd != NULL) p->b[0] = (0.5 * k1 * c - j * j) / l * yd[0] * yd[0];
            return;
        }
        case KIND_SPU:
        case KIND_SPRR: {
            Ujoint u = ujoint(y, yd);
            for (int leg = 0; leg < 2; ++leg) {
                if ((int)row[0] == KIND_SPU)
                    spu_leg(&u, row + LEGS + 6 * leg, p->l + leg, p->j + MAX_DOF * leg, p->b + leg);
                else
                    sprr_leg(&u, row + LEGS + 10 * leg, p->l + leg, p->j + MAX_DOF * leg, p->b + leg);
            }
            return;
        }
        case KIND_COPY: { /* J = I, bias 0 (pose() only: ik and fk copy the values) */
            int m = (int)row[1];
            for (int i = 0; i < m; ++i) {
                for (int k = 0; k < m; ++k) p->j[MAX_DOF * i + k] = i == k ? 1.0 : 0.0;
                p->l[i] = y[i];
                p->b[i] = 0.0;
            }
            return;
        }
        default: { /* KIND_LINEAR: J = T, bias 0 */
            int m = (int)row[1];
            for (int i = 0; i < m; ++i)
                for (int k = 0; k < m; ++k) p->j[MAX_DOF * i + k] = row[5 + 3 * i + k];
            matvec(m, p->j, y, NULL, p->l, 0);
            for (int i = 0; i < m; ++i) p->b[i] = 0.0;
        }
    }
}

/* The unit's condition number at the pose: h_max / |J| (RRPR), cond_2(J) in closed form (2x2), cond(T). */
double unit_condition(const double *row, const Pose *p) {
    int kind = (int)row[0];
    if (kind == KIND_RRPR) return row[9] / fabs(p->j[0]);
    if (kind == KIND_LINEAR) return row[4];
    if (kind == KIND_COPY) return 1.0;
    const double *j = p->j;
    double frob = j[0] * j[0] + j[1] * j[1] + j[3] * j[3] + j[4] * j[4];
    double det = j[0] * j[4] - j[1] * j[3];
    double disc = frob * frob - 4.0 * det * det;
    disc = sqrt(disc < 0.0 ? 0.0 : disc); /* NaN kept */
    return det != 0.0 ? (frob + disc) / (2.0 * fabs(det)) : INFINITY;
}

/* x = J^-T t (transpose) or J^-1 t; T^-1 for linear units, closed form for one and two joints. 1 if J is singular. */
static int unit_solve(const double *row, const double *j, const double *t, double *x, int transpose) {
    switch ((int)row[1] == 1 && (int)row[0] != KIND_LINEAR ? 1 : (int)row[0] == KIND_LINEAR ? 0 : 2) {
        case 0: {
            double tinv[MAX_DOF * MAX_DOF];
            int m = (int)row[1];
            for (int i = 0; i < m; ++i)
                for (int k = 0; k < m; ++k) tinv[MAX_DOF * i + k] = row[14 + 3 * i + k];
            matvec(m, tinv, t, NULL, x, transpose);
            return 0;
        }
        case 1:
            x[0] = t[0] / j[0];
            return j[0] == 0.0;
        default: {
            double j00 = j[0], j01 = j[1], j10 = j[3], j11 = j[4], det = j00 * j11 - j01 * j10;
            double a = transpose ? j10 : j01, c = transpose ? j01 : j10;
            x[0] = (j11 * t[0] - a * t[1]) / det;
            x[1] = (j00 * t[1] - c * t[0]) / det;
            return det == 0.0;
        }
    }
}

/* y wrapped to [-pi, pi] (Python's float % takes the divisor's sign). */
static double wrap(double y) {
    if (-M_PI <= y && y <= M_PI) return y;
    double m = fmod(y + M_PI, 2.0 * M_PI);
    if (m < 0.0) m += 2.0 * M_PI;
    return m - M_PI;
}

/* Newton on IK(y) = l of a 2-DOF unit (HyRoDyn's approach), warm from ``guess`` or cold from J(0)^-1 (l - l0),
 * steps clamped to max_step; the iterations, or FK_NOT_CONVERGED / FK_WRONG_MODE (det J of another sign than at
 * the zero pose). y comes back wrapped to [-pi, pi], with the pose (J) at exactly that y. */
static int platform_newton(const double *row, const double *t, const double *guess, double *y, Pose *p,
                           double *residual) {
    double mode = row[10], tol = row[11], max_step = row[13];
    int cap = (int)row[12];
    if (guess != NULL) {
        y[0] = guess[0];
        y[1] = guess[1];
    } else {
        double d0 = t[0] - row[4], d1 = t[1] - row[5];
        y[0] = row[6] * d0 + row[7] * d1;
        y[1] = row[8] * d0 + row[9] * d1;
    }
    for (int iteration = 0; iteration <= cap; ++iteration) {
        unit_pose(row, y, NULL, p);
        double r0 = p->l[0] - t[0], r1 = p->l[1] - t[1];
        *residual = isnan(r0) || isnan(r1) ? NAN : fmax(fabs(r0), fabs(r1));
        const double *j = p->j;
        double det = j[0] * j[4] - j[1] * j[3];
        if (*residual <= tol) {
            if (det * mode <= 0.0) return FK_WRONG_MODE;
            double w0 = wrap(y[0]), w1 = wrap(y[1]);
            if (w0 != y[0] || w1 != y[1]) {
                y[0] = w0;
                y[1] = w1;
                unit_pose(row, y, NULL, p);
            }
            return iteration;
        }
        if (iteration == cap || !(isfinite(*residual) && det != 0.0)) break;
        double d[2];
        unit_solve(row, j, (double[2]){r0, r1}, d, 0);
        double step = fmax(fabs(d[0]), fabs(d[1]));
        if (step > max_step) {
            d[0] *= max_step / step;
            d[1] *= max_step / step;
        }
        y[0] -= d[0];
        y[1] -= d[1];
    }
    return FK_NOT_CONVERGED;
}

/* Forward kinematics of one unit: closed form (RRPR: cos(phi) = (k0 - l^2) / k1, one branch), Newton (2-DOF),
 * T^-1 l (linear); the iterations (0 in closed form) or a FK_* code, with the pose at the returned y. */
static int unit_forward(const double *row, const double *l, const double *guess, double *y, Pose *p,
                        double *residual) {
    *residual = 0.0;
    switch ((int)row[0]) {
        case KIND_RRPR: {
            double k0 = row[5], k1 = row[6], c = (k0 - l[0] * l[0]) / k1;
            if (!(fabs(c) <= 1.0 + ROUNDING)) {
                double lo = sqrt(k0 - k1), hi = sqrt(k0 + k1);
                *residual = isfinite(l[0]) ? fmax(fmax(lo - l[0], l[0] - hi), 0.0) : INFINITY;
                return FK_UNREACHABLE;
            }
            y[0] = row[8] * acos(c < -1.0 ? -1.0 : c > 1.0 ? 1.0 : c) - row[4];
            unit_pose(row, y, NULL, p);
            return 0;
        }
        case KIND_SPU:
        case KIND_SPRR:
            return platform_newton(row, l, guess, y, p, residual);
        default: {
            double zeros[MAX_DOF] = {0.0, 0.0, 0.0};
            unit_solve(row, NULL, l, y, 0);
            unit_pose(row, zeros, NULL, p); /* J = T everywhere */
            return 0;
        }
    }
}

/* out = x: the m values of a pass-through unit. */
static void copy(int m, const double *x, double *out) {
    for (int i = 0; i < m; ++i) out[i] = x[i];
}


/* Joints -> actuators of one unit: l, J v, J a + bias, J^-T tau; -1 when the force map is refused. */
int ik_unit(const double *row, double *const *x, double max_condition, double *info) {
    int m = (int)row[1], jj = (int)row[2], aa = (int)row[3];
    const double *q = x[0] + jj, *v = x[1], *a = x[2], *tau = x[3];
    double *ld = x[5], *ldd = x[6], *f = x[7];
    int status = 0;
    double condition = 1.0;
    if ((int)row[0] == KIND_COPY) {
        copy(m, q, x[4] + aa);
        if (v != NULL) copy(m, v + jj, ld + aa);
        if (a != NULL) copy(m, a + jj, ldd + aa);
        if (tau != NULL) copy(m, tau + jj, f + aa);
    } else {
        Pose p;
        unit_pose(row, q, a != NULL ? v + jj : NULL, &p);
        copy(m, p.l, x[4] + aa);
        if (tau != NULL) {
            condition = unit_condition(row, &p);
            unit_solve(row, p.j, tau + jj, f + aa, 1);
        }
        if (v != NULL) matvec(m, p.j, v + jj, NULL, ld + aa, 0);
        if (a != NULL) matvec(m, p.j, a + jj, p.b, ldd + aa, 0);
    }
    if (tau != NULL && !(condition <= max_condition)) status = -1;
    if (info != NULL) {
        info[0] = status;
        info[1] = condition;
    }
    return status;
}

/* Actuators -> joints of one unit: y, J^-1 ld, J^T f; the iterations, or a FK_* code. */
int fk_unit(const double *row, double *const *x, double max_condition, double *info) {
    int m = (int)row[1], jj = (int)row[2], aa = (int)row[3];
    const double *l = x[0] + aa, *ld = x[1], *f = x[2], *guess = x[3];
    double *v = x[5], *tau = x[6], residual = 0.0;
    int status = 0;
    (void)max_condition;
    if ((int)row[0] == KIND_COPY) {
        copy(m, l, x[4] + jj);
        if (ld != NULL) copy(m, ld + aa, v + jj);
        if (f != NULL) copy(m, f + aa, tau + jj);
    } else {
        Pose p;
        status = unit_forward(row, l, guess != NULL ? guess + jj : NULL, x[4] + jj, &p, &residual);
        if (status >= 0) {
            if (ld != NULL && unit_solve(row, p.j, ld + aa, v + jj, 0)) status = FK_SINGULAR;
            if (f != NULL) matvec(m, p.j, f + aa, NULL, tau + jj, 1);
        }
    }
    if (info != NULL) {
        info[0] = status;
        info[1] = residual;
    }
    return status;
}
