/* The Python module _compiled: the calls that run the submechanisms' maths (unit_maps.c) over N samples of a table of
 * units. A model's maps run on a table of its one row; RobotMapper's on a table of every unit of the robot, so the
 * 1 kHz control cycle's call is a batch of one through the same code as a whole trajectory.
 *
 *   ik(table, n, q, v, a, tau, max_condition, l, ld, ldd, f, info)   joints -> actuators (l, J v, J a + bias, J^-T tau)
 *   fk(table, n, l, ld, f, q_guess, q, v, tau, info)                 actuators -> joints (FK, J^-1 ld, J^T f)
 *   pose(table, n, y, yd, jac, bias, cond)                           J, bias and condition of a one-row table
 *
 * Optional arguments are None (the matching outputs too). ik and fk return -1, or sample * rows + row of the first
 * unit that failed (a refusal near a singular pose, lengths that do not assemble); with ``info`` (n x rows x 2) they
 * go on and record per unit and sample the status (ik: 0 or -1; fk: Newton iterations >= 0 or a FK_* code) and a
 * detail (ik: the condition number; fk: the final residual [m]).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "unit_maps.h"

#define MAX_ARRAYS 8

/* One array argument: its name, which vectors' width it has (0: joints, 1: actuators), whether it is written, the
 * argument that must be given with it (-1: none) and the one it needs (-1: none). */
typedef struct {
    const char *name;
    int actuators, output, pair, needs;
} Spec;

static const Spec IK_ARGS[] = {{"q", 0, 0, 4, -1},   {"v", 0, 0, 5, -1},   {"a", 0, 0, 6, 1},    {"tau", 0, 0, 7, -1},
                               {"l", 1, 1, -1, -1},  {"ld", 1, 1, -1, -1}, {"ldd", 1, 1, -1, -1}, {"f", 1, 1, -1, -1}};
static const Spec FK_ARGS[] = {{"l", 1, 0, 4, -1},  {"ld", 1, 0, 5, -1}, {"f", 1, 0, 6, -1}, {"q_guess", 0, 0, -1, -1},
                               {"q", 0, 1, -1, -1}, {"v", 0, 1, -1, -1}, {"tau", 0, 1, -1, -1}};

typedef struct {
    Py_buffer view[MAX_ARRAYS + 2];
    int count;
} Buffers;

static void release(Buffers *b) {
    for (int i = 0; i < b->count; ++i) PyBuffer_Release(&b->view[i]);
    b->count = 0;
}

/* The C-contiguous float64 data of ``obj`` (NULL for None): ``values`` of them, or with ``per_sample`` set, any
 * whole number per sample of the n, written there. -1 with an exception (a BufferError if not C-contiguous). */
static int take(Buffers *b, PyObject *obj, int writable, Py_ssize_t values, Py_ssize_t *per_sample, Py_ssize_t n,
                const char *what, double **out) {
    *out = NULL;
    if (obj == Py_None) return 0;
    Py_buffer *view = &b->view[b->count];
    if (PyObject_GetBuffer(obj, view, writable ? PyBUF_WRITABLE : PyBUF_SIMPLE) != 0) return -1;
    b->count++;
    Py_ssize_t count = view->len / (Py_ssize_t)sizeof(double);
    if (per_sample != NULL) {
        *per_sample = n > 0 ? count / n : 0;
        values = *per_sample * n;
    }
    if (n <= 0 || view->len != values * (Py_ssize_t)sizeof(double)) {
        PyErr_Format(PyExc_ValueError, "%s: %zd float64 expected, got %zd bytes", what, values, view->len);
        return -1;
    }
    *out = view->buf;
    return 0;
}

/* The table's rows, checked against the joint and actuator widths; -1 with an exception. */
static Py_ssize_t table_rows(Buffers *b, PyObject *obj, Py_ssize_t joints, Py_ssize_t actuators, double **table) {
    *table = NULL;
    Py_buffer *view = &b->view[b->count];
    if (PyObject_GetBuffer(obj, view, PyBUF_SIMPLE) != 0) return -1;
    b->count++;
    Py_ssize_t rows = view->len / (ROW_WIDTH * (Py_ssize_t)sizeof(double));
    if (view->len != rows * ROW_WIDTH * (Py_ssize_t)sizeof(double)) {
        PyErr_SetString(PyExc_ValueError, "table: rows of ROW_WIDTH float64 expected");
        return -1;
    }
    const double *t = view->buf;
    double jw = (double)joints, aw = (double)actuators;
    for (Py_ssize_t r = 0; r < rows; ++r) { /* float compares only: this runs on every call */
        const double *row = t + r * ROW_WIDTH;
        double kind = row[0], m = row[1];
        int ok = (kind == KIND_COPY     ? m >= 1.0
                  : kind == KIND_LINEAR ? m >= 1.0 && m <= MAX_DOF
                  : kind == KIND_RRPR   ? m == 1.0
                                        : (kind == KIND_SPU || kind == KIND_SPRR) && m == 2.0) &&
                 row[2] >= 0.0 && row[3] >= 0.0 && row[2] + m <= jw && row[3] + m <= aw;
        if (!ok) {
            PyErr_Format(PyExc_ValueError, "table row %zd: not a unit within %zd joints and %zd actuators", r,
                         joints, actuators);
            return -1;
        }
    }
    *table = view->buf;
    return rows;
}

/* One ik or fk call: (table, n, inputs..., [max_condition,] outputs..., info) -> -1 or the first failure. The first
 * input and the first output set the widths; every unit of the table maps every sample (all of them with ``info``,
 * else up to the first failure). */
static PyObject *run(PyObject *args, const Spec *spec, int count, int inputs, int with_condition, UnitMap unit) {
    Py_ssize_t size = PyTuple_GET_SIZE(args);
    if (size != 3 + count + with_condition) {
        PyErr_Format(PyExc_TypeError, "function takes exactly %d arguments (%zd given)", 3 + count + with_condition,
                     size);
        return NULL;
    }
    PyObject *obj[MAX_ARRAYS];
    double max_condition = 0.0, *x[MAX_ARRAYS], *table, *info;
    Py_ssize_t n = PyLong_AsSsize_t(PyTuple_GET_ITEM(args, 1)), k = 2;
    for (int i = 0; i < count; ++i) {
        if (i == inputs && with_condition) max_condition = PyFloat_AsDouble(PyTuple_GET_ITEM(args, k++));
        obj[i] = PyTuple_GET_ITEM(args, k++);
    }
    if (PyErr_Occurred()) return NULL;
    Buffers b = {.count = 0};
    Py_ssize_t width[2] = {0, 0}, rows = 0;
    int bad = take(&b, obj[0], 0, 0, &width[spec[0].actuators], n, spec[0].name, &x[0]) != 0 ||
              take(&b, obj[inputs], 1, 0, &width[spec[inputs].actuators], n, spec[inputs].name, &x[inputs]) != 0 ||
              (rows = table_rows(&b, PyTuple_GET_ITEM(args, 0), width[0], width[1], &table)) < 0;
    for (int i = 1; i < count && !bad; ++i)
        if (i != inputs)
            bad = take(&b, obj[i], spec[i].output, n * width[spec[i].actuators], NULL, n, spec[i].name, &x[i]) != 0;
    if (!bad) bad = take(&b, PyTuple_GET_ITEM(args, size - 1), 1, n * rows * 2, NULL, n, "info", &info) != 0;
    for (int i = 0; i < count && !bad; ++i) {
        int pair = spec[i].pair, needs = spec[i].needs;
        if ((x[i] == NULL && i == 0) || (pair >= 0 && (x[i] == NULL) != (x[pair] == NULL)) ||
            (needs >= 0 && x[i] != NULL && x[needs] == NULL)) {
            PyErr_Format(PyExc_ValueError, "%s: every given input needs its output (%s)",
                         with_condition ? "ik" : "fk", spec[i].name);
            bad = 1;
        }
    }
    if (bad) {
        release(&b);
        return NULL;
    }
    long failed = -1;
    for (Py_ssize_t s = 0; s < n && (failed < 0 || info != NULL); ++s) {
        double *p[MAX_ARRAYS];
        for (int i = 0; i < count; ++i) p[i] = x[i] != NULL ? x[i] + s * width[spec[i].actuators] : NULL;
        for (Py_ssize_t r = 0; r < rows; ++r) {
            double *unit_info = info != NULL ? info + 2 * (s * rows + r) : NULL;
            if (unit(table + r * ROW_WIDTH, p, max_condition, unit_info) < 0 && failed < 0) {
                failed = (long)(s * rows + r);
                if (info == NULL) break;
            }
        }
    }
    release(&b);
    return PyLong_FromLong(failed);
}

static PyObject *ik(PyObject *self, PyObject *args) { return run(args, IK_ARGS, 8, 4, 1, ik_unit); }

static PyObject *fk(PyObject *self, PyObject *args) { return run(args, FK_ARGS, 7, 4, 0, fk_unit); }

static PyObject *pose(PyObject *self, PyObject *args) {
    PyObject *table_obj, *y_obj, *yd_obj, *out[3];
    Py_ssize_t n;
    double *table, *y, *yd, *jac, *bias, *cond;
    if (!PyArg_ParseTuple(args, "OnOOOOO", &table_obj, &n, &y_obj, &yd_obj, &out[0], &out[1], &out[2])) return NULL;
    Buffers b = {.count = 0};
    Py_ssize_t m = 0, rows = 0;
    int bad = take(&b, y_obj, 0, 0, &m, n, "y", &y) != 0 || (rows = table_rows(&b, table_obj, m, m, &table)) < 0;
    if (!bad && (rows != 1 || m > MAX_DOF)) {
        PyErr_SetString(PyExc_ValueError, "pose: a table of one unit expected");
        bad = 1;
    }
    if (!bad)
        bad = take(&b, yd_obj, 0, n * m, NULL, n, "yd", &yd) != 0 ||
              take(&b, out[0], 1, n * m * m, NULL, n, "jac", &jac) != 0 ||
              take(&b, out[1], 1, n * m, NULL, n, "bias", &bias) != 0 ||
              take(&b, out[2], 1, n, NULL, n, "cond", &cond) != 0;
    if (!bad && (bias != NULL) != (yd != NULL)) {
        PyErr_SetString(PyExc_ValueError, "pose: the bias needs yd");
        bad = 1;
    }
    if (bad) {
        release(&b);
        return NULL;
    }
    for (Py_ssize_t s = 0; s < n; ++s) {
        Pose p;
        unit_pose(table, y + s * m, yd != NULL ? yd + s * m : NULL, &p);
        for (int i = 0; i < m; ++i) {
            if (jac != NULL)
                for (int k = 0; k < m; ++k) jac[s * m * m + m * i + k] = p.j[MAX_DOF * i + k];
            if (bias != NULL) bias[s * m + i] = p.b[i];
        }
        if (cond != NULL) cond[s] = unit_condition(table, &p);
    }
    release(&b);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"ik", ik, METH_VARARGS, "ik(table, n, q, v, a, tau, max_condition, l, ld, ldd, f, info) -> -1 or the first failure"},
    {"fk", fk, METH_VARARGS, "fk(table, n, l, ld, f, q_guess, q, v, tau, info) -> -1 or the first failure"},
    {"pose", pose, METH_VARARGS, "pose(table, n, y, yd, jac, bias, cond) -> None (a table of one unit)"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_compiled", NULL, -1, methods};

PyMODINIT_FUNC PyInit__compiled(void) {
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    if (PyModule_AddIntConstant(m, "ROW_WIDTH", ROW_WIDTH) != 0 || PyModule_AddIntConstant(m, "MAX_DOF", MAX_DOF) != 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
