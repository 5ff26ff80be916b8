/* The whole robot's joint <-> actuator maps of ONE sample in C: the control cycle's two mapping steps.
 *
 * The same arithmetic, in the same order, as the submechanisms' Python float paths
 * (``to_actuator_space_floats`` / ``to_joint_space_floats`` of lambda_rrpr.py, spu.py, ankle_sprr.py and
 * serial.py), which stay the reference: the Python wrapper (compiled.py) packs each unit's constants into
 * one row of a table and falls back to them for anything unusual. Python spends ~60 us (IK) and ~75 us
 * (FK) a cycle here on the interpreter's per-float work; this takes a few microseconds.
 *
 * Row layout (float64, ROW_WIDTH columns): kind, dof, first joint, first actuator, then per kind:
 *   COPY    pass-through of one joint (dof 1)
 *   RRPR    phi0, k0, k1, r12, sign, moment_arm_max
 *   SPU     l00, l01, jinv0[4], mode, tolerance, max_iterations, max_step, legs 2 x (b[3], e0[3])
 *   SPRR    as SPU, legs 2 x (s[3], f0[3], a0[3], r)
 *   LINEAR  T[3][3] (l = T y), Tinv[3][3], cond(T)
 *
 * ik(table, q, v, tau, max_condition, l, ld, f) and fk(table, l, ld, f, q_guess, q, v, tau) write the
 * outputs (32 float64 each) and return -1, or the row whose unit needs the Python path: a refusal
 * (singular pose, lengths that do not assemble) that Python reports with its reason.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#define ROW_WIDTH 48
#define KIND_COPY 0
#define KIND_RRPR 1
#define KIND_SPU 2
#define KIND_SPRR 3
#define KIND_LINEAR 4
#define LEGS 14 /* first leg column of SPU and SPRR rows */

typedef struct {
    double l1, l2, j00, j01, j10, j11;
} Fused;

/* (l1, l2, J) of a 2-SPU+1U unit at (c0, s0, c1, s1): Platform2SPU1U._fused without rates. */
static Fused spu_fused(const double *row, double c0, double s0, double c1, double s1) {
    double out[6];
    for (int leg = 0; leg < 2; ++leg) {
        const double *p = row + LEGS + 6 * leg;
        double bx = p[0], by = p[1], bz = p[2], ex = p[3], ey = p[4], ez = p[5];
        double px = c1 * ex + s1 * ez;
        double wz = c1 * ez - s1 * ex;
        double py = c0 * ey - s0 * wz;
        double pz = s0 * ey + c0 * wz;
        double dx = px - bx, dy = py - by, dz = pz - bz;
        double l = pow(dx * dx + dy * dy + dz * dz, 0.5);
        double my = bz * px - bx * pz, mz = bx * py - by * px;
        out[3 * leg] = l;
        out[3 * leg + 1] = (by * pz - bz * py) / l;
        out[3 * leg + 2] = (c0 * my + s0 * mz) / l;
    }
    Fused r = {out[0], out[3], out[1], out[2], out[4], out[5]};
    return r;
}

/* The same for a 2-SPRR+1U ankle: Ankle2SPRR1U._fused without rates. */
static Fused sprr_fused(const double *row, double c0, double s0, double c1, double s1) {
    double out[6];
    for (int leg = 0; leg < 2; ++leg) {
        const double *p = row + LEGS + 10 * leg;
        double sx = p[0], sy = p[1], sz = p[2], fx0 = p[3], fy0 = p[4], fz0 = p[5];
        double ax0 = p[6], ay0 = p[7], az0 = p[8], r = p[9];
        double fx = c1 * fx0 + s1 * fz0;
        double t = c1 * fz0 - s1 * fx0;
        double fy = c0 * fy0 - s0 * t;
        double fz = s0 * fy0 + c0 * t;
        double ax = c1 * ax0 + s1 * az0;
        t = c1 * az0 - s1 * ax0;
        double ay = c0 * ay0 - s0 * t;
        double az = s0 * ay0 + c0 * t;
        double tx = sx - fx, ty = sy - fy, tz = sz - fz;
        double alpha = ax * tx + ay * ty + az * tz;
        double px = tx - alpha * ax, py = ty - alpha * ay, pz = tz - alpha * az;
        double rho = pow(px * px + py * py + pz * pz, 0.5);
        double e = rho - r;
        double l = pow(alpha * alpha + e * e, 0.5);
        double g = r / rho;
        double kx = fx + g * px, ky = fy + g * py, kz = fz + g * pz;
        double my = sz * kx - sx * kz, mz = sx * ky - sy * kx;
        out[3 * leg] = l;
        out[3 * leg + 1] = (sy * kz - sz * ky) / l;
        out[3 * leg + 2] = (c0 * my + s0 * mz) / l;
    }
    Fused r = {out[0], out[3], out[1], out[2], out[4], out[5]};
    return r;
}

static Fused platform_fused(const double *row, double y0, double y1) {
    double c0 = cos(y0), s0 = sin(y0), c1 = cos(y1), s1 = sin(y1);
    return (int)row[0] == KIND_SPU ? spu_fused(row, c0, s0, c1, s1) : sprr_fused(row, c0, s0, c1, s1);
}

/* y wrapped to [-pi, pi] as spu._wrap does (Python's float % takes the divisor's sign). */
static double wrap(double y) {
    if (-M_PI <= y && y <= M_PI) return y;
    double m = fmod(y + M_PI, 2.0 * M_PI);
    if (m != 0.0 && m < 0.0) m += 2.0 * M_PI;
    return m - M_PI;
}

/* Newton forward kinematics of a 2-DOF unit (UniversalJointPlatform._newton_floats); 0 or -1 (Python decides). */
static int platform_newton(const double *row, double t0, double t1, double y0, double y1, double *y, Fused *jac) {
    double tol = row[11], max_step = row[13], mode = row[10];
    int cap = (int)row[12];
    for (int iteration = 0; iteration <= cap; ++iteration) {
        Fused k = platform_fused(row, y0, y1);
        double r0 = k.l1 - t0, r1 = k.l2 - t1;
        if (isnan(r0) || isnan(r1)) return -1; /* Python's max() and fmax() treat NaN differently */
        double residual = fmax(fabs(r0), fabs(r1));
        double det = k.j00 * k.j11 - k.j01 * k.j10;
        if (residual <= tol) {
            if (det * mode <= 0.0) return -1;
            double w0 = wrap(y0), w1 = wrap(y1);
            if (w0 != y0 || w1 != y1) k = platform_fused(row, w0, w1);
            y[0] = w0;
            y[1] = w1;
            *jac = k;
            return 0;
        }
        if (iteration == cap || !(isfinite(residual) && det != 0.0)) return -1;
        double d0 = (k.j11 * r0 - k.j01 * r1) / det;
        double d1 = (k.j00 * r1 - k.j10 * r0) / det;
        double step = fmax(fabs(d0), fabs(d1));
        if (step > max_step) {
            d0 = d0 * (max_step / step);
            d1 = d1 * (max_step / step);
        }
        y0 -= d0;
        y1 -= d1;
    }
    return -1;
}

/* One unit of the inverse map; 0, or -1 when Python must decide (a refusal). */
static int ik_row(const double *row, const double *q, const double *v, const double *tau, double max_condition,
                  double *l, double *ld, double *f) {
    int kind = (int)row[0], j = (int)row[2], a = (int)row[3];
    switch (kind) {
        case KIND_COPY:
            l[a] = q[j];
            ld[a] = v[j];
            f[a] = tau[j];
            return 0;
        case KIND_RRPR: {
            double phi0 = row[4], k0 = row[5], k1 = row[6], r12 = row[7], arm_max = row[9];
            double phi = phi0 + q[j];
            double c = cos(phi);
            double length = sqrt(k0 - k1 * c);
            double jac = r12 * sin(phi) / length;
            if (!(fabs(jac) * max_condition >= arm_max) || jac == 0.0) return -1;
            l[a] = length;
            f[a] = tau[j] / jac;
            ld[a] = jac * v[j];
            return 0;
        }
        case KIND_SPU:
        case KIND_SPRR: {
            Fused k = platform_fused(row, q[j], q[j + 1]);
            double w0 = v[j], w1 = v[j + 1];
            double det = k.j00 * k.j11 - k.j01 * k.j10;
            double frob = k.j00 * k.j00 + k.j01 * k.j01 + k.j10 * k.j10 + k.j11 * k.j11;
            double disc = frob * frob - 4.0 * det * det;
            disc = sqrt(disc < 0.0 ? 0.0 : disc);
            double cond = det != 0.0 ? (frob + disc) / (2.0 * fabs(det)) : INFINITY;
            if (!(cond <= max_condition)) return -1;
            double t0 = tau[j], t1 = tau[j + 1];
            l[a] = k.l1;
            l[a + 1] = k.l2;
            ld[a] = k.j00 * w0 + k.j01 * w1;
            ld[a + 1] = k.j10 * w0 + k.j11 * w1;
            f[a] = (k.j11 * t0 - k.j10 * t1) / det;
            f[a + 1] = (k.j00 * t1 - k.j01 * t0) / det;
            return 0;
        }
        case KIND_LINEAR: {
            int m = (int)row[1];
            const double *t = row + 4, *tinv = row + 13;
            if (!(row[22] <= max_condition)) return -1;
            for (int i = 0; i < m; ++i) {
                double sl = 0.0, sld = 0.0, sf = 0.0;
                for (int k = 0; k < m; ++k) {
                    double tik = t[3 * i + k], fik = tinv[3 * k + i]; /* f = Tinv^T tau */
                    if (tik != 0.0) {
                        sl += tik * q[j + k];
                        sld += tik * v[j + k];
                    }
                    if (fik != 0.0) sf += fik * tau[j + k];
                }
                l[a + i] = sl;
                ld[a + i] = sld;
                f[a + i] = sf;
            }
            return 0;
        }
        default:
            return -1;
    }
}

/* One unit of the forward map; 0, or -1 when Python must decide. */
static int fk_row(const double *row, const double *l, const double *ld, const double *f, const double *guess,
                  double *q, double *v, double *tau) {
    int kind = (int)row[0], j = (int)row[2], a = (int)row[3];
    switch (kind) {
        case KIND_COPY:
            q[j] = l[a];
            v[j] = ld[a];
            tau[j] = f[a];
            return 0;
        case KIND_RRPR: {
            double phi0 = row[4], k0 = row[5], k1 = row[6], r12 = row[7], sign = row[8];
            double length = l[a];
            double c = (k0 - length * length) / k1;
            if (!(fabs(c) <= 1.0)) return -1;
            double y = sign * acos(c) - phi0;
            double phi = phi0 + y;
            double jac = r12 * sin(phi) / sqrt(k0 - k1 * cos(phi));
            if (jac == 0.0) return -1;
            q[j] = y;
            v[j] = ld[a] / jac;
            tau[j] = jac * f[a];
            return 0;
        }
        case KIND_SPU:
        case KIND_SPRR: {
            double y[2];
            Fused k;
            if (platform_newton(row, l[a], l[a + 1], guess[j], guess[j + 1], y, &k) != 0) return -1;
            double det = k.j00 * k.j11 - k.j01 * k.j10;
            if (det == 0.0) return -1;
            double u0 = ld[a], u1 = ld[a + 1], f0 = f[a], f1 = f[a + 1];
            q[j] = y[0];
            q[j + 1] = y[1];
            v[j] = (k.j11 * u0 - k.j01 * u1) / det;
            v[j + 1] = (k.j00 * u1 - k.j10 * u0) / det;
            tau[j] = k.j00 * f0 + k.j10 * f1;
            tau[j + 1] = k.j01 * f0 + k.j11 * f1;
            return 0;
        }
        case KIND_LINEAR: {
            int m = (int)row[1];
            const double *t = row + 4, *tinv = row + 13;
            for (int i = 0; i < m; ++i) {
                double sq = 0.0, sv = 0.0, st = 0.0;
                for (int k = 0; k < m; ++k) {
                    double ik = tinv[3 * i + k], tk = t[3 * k + i]; /* tau = T^T f */
                    if (ik != 0.0) {
                        sq += ik * l[a + k];
                        sv += ik * ld[a + k];
                    }
                    if (tk != 0.0) st += tk * f[a + k];
                }
                q[j + i] = sq;
                v[j + i] = sv;
                tau[j + i] = st;
            }
            return 0;
        }
        default:
            return -1;
    }
}

/* The buffers of one call: a (rows, ROW_WIDTH) table and seven vectors of 32 float64 (three written). */
typedef struct {
    Py_buffer table, in[4], out[3];
    int n_in;
} Buffers;

static void release(Buffers *b) {
    PyBuffer_Release(&b->table);
    for (int i = 0; i < b->n_in; ++i) PyBuffer_Release(&b->in[i]);
    for (int i = 0; i < 3; ++i) PyBuffer_Release(&b->out[i]);
}

static int check(Buffers *b) {
    if (b->table.len % (ROW_WIDTH * sizeof(double)) != 0) {
        PyErr_SetString(PyExc_ValueError, "table: rows of ROW_WIDTH float64 expected");
        return -1;
    }
    for (int i = 0; i < b->n_in; ++i)
        if (b->in[i].len != 32 * (Py_ssize_t)sizeof(double)) {
            PyErr_SetString(PyExc_ValueError, "inputs: 32 float64 each expected");
            return -1;
        }
    for (int i = 0; i < 3; ++i)
        if (b->out[i].len != 32 * (Py_ssize_t)sizeof(double)) {
            PyErr_SetString(PyExc_ValueError, "outputs: 32 float64 each expected");
            return -1;
        }
    return 0;
}

static PyObject *ik(PyObject *self, PyObject *args) {
    Buffers b = {.n_in = 3};
    double max_condition;
    if (!PyArg_ParseTuple(args, "y*y*y*y*dw*w*w*", &b.table, &b.in[0], &b.in[1], &b.in[2], &max_condition,
                          &b.out[0], &b.out[1], &b.out[2]))
        return NULL;
    if (check(&b) != 0) {
        release(&b);
        return NULL;
    }
    const double *table = b.table.buf;
    Py_ssize_t rows = b.table.len / (ROW_WIDTH * sizeof(double));
    long failed = -1;
    for (Py_ssize_t r = 0; r < rows && failed < 0; ++r)
        if (ik_row(table + r * ROW_WIDTH, b.in[0].buf, b.in[1].buf, b.in[2].buf, max_condition, b.out[0].buf,
                   b.out[1].buf, b.out[2].buf) != 0)
            failed = (long)r;
    release(&b);
    return PyLong_FromLong(failed);
}

static PyObject *fk(PyObject *self, PyObject *args) {
    Buffers b = {.n_in = 4};
    if (!PyArg_ParseTuple(args, "y*y*y*y*y*w*w*w*", &b.table, &b.in[0], &b.in[1], &b.in[2], &b.in[3], &b.out[0],
                          &b.out[1], &b.out[2]))
        return NULL;
    if (check(&b) != 0) {
        release(&b);
        return NULL;
    }
    const double *table = b.table.buf;
    Py_ssize_t rows = b.table.len / (ROW_WIDTH * sizeof(double));
    long failed = -1;
    for (Py_ssize_t r = 0; r < rows && failed < 0; ++r)
        if (fk_row(table + r * ROW_WIDTH, b.in[0].buf, b.in[1].buf, b.in[2].buf, b.in[3].buf, b.out[0].buf,
                   b.out[1].buf, b.out[2].buf) != 0)
            failed = (long)r;
    release(&b);
    return PyLong_FromLong(failed);
}

static PyMethodDef methods[] = {
    {"ik", ik, METH_VARARGS, "ik(table, q, v, tau, max_condition, l, ld, f) -> -1 or the row Python must map"},
    {"fk", fk, METH_VARARGS, "fk(table, l, ld, f, q_guess, q, v, tau) -> -1 or the row Python must map"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_compiled", NULL, -1, methods};

PyMODINIT_FUNC PyInit__compiled(void) {
    PyObject *m = PyModule_Create(&module);
    if (m != NULL && PyModule_AddIntConstant(m, "ROW_WIDTH", ROW_WIDTH) != 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
