/*
 * Sums of the least-squares VAD fit of every (scan, gate) (cwproc.stages.vad_fit), in one
 * pass over the rays each and without the GIL.
 *
 * normal_sums(velocity, design, valid, ata, aty, n_rays, n_scan, n_ray, n_gate)
 *
 *   velocity: (S, R, G) doubles, design: (S, R, 3) doubles (finite), valid: (S, R, G)
 *   bytes (numpy bool); written: ata (S, G, 3, 3) = sum_r w a_j a_k, aty (S, G, 3) =
 *   sum_r w y a_j and n_rays (S, G) = sum_r w, doubles, with w = 1 where valid, else 0
 *   (and y taken as 0 there: a value that is not valid, NaN or not, adds nothing).
 *   Smalikho (2020), eq. 1: the normal equations of V_r = a . (u, v, w) per scan and gate.
 *
 * residual_ssr(velocity, design, valid, beta, ssr, n_scan, n_ray, n_gate)
 *
 *   beta: (S, G, 3) doubles (finite); written: ssr (S, G) = sum over the valid rays of
 *   (y - a . beta)^2, the residual sum of squares of the fit.
 *
 * All arrays C-contiguous. The gates are the inner loop, each gate summing its rays in
 * ray order (independent sums, so the compiler may vectorise across gates without
 * reordering any sum). numpy's version (vad_fit.normal_sums_numpy, residual_ssr_numpy)
 * sums by BLAS matrix products in another order: the two agree to round-off (1e-15
 * relative), not to the bit.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

static void sums(const double *y, const double *design, const char *valid, double *ata,
                 double *aty, double *n_rays, Py_ssize_t n_scan, Py_ssize_t n_ray,
                 Py_ssize_t n_gate, double *acc)
{
    /* acc: 10 planes of n_gate: aa ab ac bb bc cc (the distinct products), ya yb yc, n */
    for (Py_ssize_t s = 0; s < n_scan; s++) {
        memset(acc, 0, (size_t)(10 * n_gate) * sizeof(double));
        for (Py_ssize_t r = 0; r < n_ray; r++) {
            const double *a = design + (s * n_ray + r) * 3;
            const double p[6] = {a[0] * a[0], a[0] * a[1], a[0] * a[2],
                                 a[1] * a[1], a[1] * a[2], a[2] * a[2]};
            const double *yr = y + (s * n_ray + r) * n_gate;
            const char *vr = valid + (s * n_ray + r) * n_gate;
            double *restrict s0 = acc, *restrict s1 = acc + n_gate;
            double *restrict s2 = acc + 2 * n_gate, *restrict s3 = acc + 3 * n_gate;
            double *restrict s4 = acc + 4 * n_gate;
            double *restrict s5 = acc + 5 * n_gate, *restrict t0 = acc + 6 * n_gate;
            double *restrict t1 = acc + 7 * n_gate, *restrict t2 = acc + 8 * n_gate;
            double *restrict count = acc + 9 * n_gate;
            for (Py_ssize_t g = 0; g < n_gate; g++) {
                double w = vr[g] ? 1.0 : 0.0, yv = vr[g] ? yr[g] : 0.0;
                s0[g] += w * p[0];
                s1[g] += w * p[1];
                s2[g] += w * p[2];
                s3[g] += w * p[3];
                s4[g] += w * p[4];
                s5[g] += w * p[5];
                t0[g] += yv * a[0];
                t1[g] += yv * a[1];
                t2[g] += yv * a[2];
                count[g] += w;
            }
        }
        for (Py_ssize_t g = 0; g < n_gate; g++) {
            double *m = ata + (s * n_gate + g) * 9;
            double aa = acc[g], ab = acc[n_gate + g], ac = acc[2 * n_gate + g];
            double bb = acc[3 * n_gate + g], bc = acc[4 * n_gate + g], cc = acc[5 * n_gate + g];
            m[0] = aa; m[1] = ab; m[2] = ac;
            m[3] = ab; m[4] = bb; m[5] = bc;
            m[6] = ac; m[7] = bc; m[8] = cc;
            double *rhs = aty + (s * n_gate + g) * 3;
            for (int j = 0; j < 3; j++) rhs[j] = acc[(6 + j) * n_gate + g];
            n_rays[s * n_gate + g] = acc[9 * n_gate + g];
        }
    }
}

static void ssr_sums(const double *y, const double *design, const char *valid,
                     const double *beta, double *ssr, Py_ssize_t n_scan, Py_ssize_t n_ray,
                     Py_ssize_t n_gate, double *b)
{
    /* b: the scan's coefficients as 3 planes of n_gate */
    for (Py_ssize_t s = 0; s < n_scan; s++) {
        double *out = ssr + s * n_gate;
        for (Py_ssize_t g = 0; g < n_gate; g++) {
            out[g] = 0.0;
            for (int j = 0; j < 3; j++) b[j * n_gate + g] = beta[(s * n_gate + g) * 3 + j];
        }
        const double *b0 = b, *b1 = b + n_gate, *b2 = b + 2 * n_gate;
        for (Py_ssize_t r = 0; r < n_ray; r++) {
            const double *a = design + (s * n_ray + r) * 3;
            const double *yr = y + (s * n_ray + r) * n_gate;
            const char *vr = valid + (s * n_ray + r) * n_gate;
            for (Py_ssize_t g = 0; g < n_gate; g++) {
                double d = yr[g] - (a[0] * b0[g] + a[1] * b1[g] + a[2] * b2[g]);
                out[g] += vr[g] ? d * d : 0.0;
            }
        }
    }
}

/* Get the buffers of objs[0..n) (C-contiguous; writable from index first_out). */
static int get_buffers(PyObject **objs, Py_buffer *views, int n, int first_out)
{
    for (int i = 0; i < n; i++) {
        int flags = PyBUF_C_CONTIGUOUS | (i >= first_out ? PyBUF_WRITABLE : 0);
        if (PyObject_GetBuffer(objs[i], &views[i], flags) < 0) {
            while (i-- > 0) PyBuffer_Release(&views[i]);
            return -1;
        }
    }
    return 0;
}

static void release(Py_buffer *views, int n)
{
    for (int i = 0; i < n; i++) PyBuffer_Release(&views[i]);
}

/* Whether each view holds at least its expected bytes; else a ValueError. */
static int check_sizes(Py_buffer *views, const Py_ssize_t *bytes, int n)
{
    for (int i = 0; i < n; i++) {
        if (views[i].len < bytes[i]) {
            PyErr_SetString(PyExc_ValueError, "an array is smaller than its shape requires");
            return -1;
        }
    }
    return 0;
}

static PyObject *normal_sums(PyObject *self, PyObject *args)
{
    PyObject *objs[6];
    Py_ssize_t S, R, G;
    if (!PyArg_ParseTuple(args, "OOOOOOnnn", &objs[0], &objs[1], &objs[2], &objs[3], &objs[4],
                          &objs[5], &S, &R, &G))
        return NULL;
    if (S < 0 || R < 0 || G < 0) {
        PyErr_SetString(PyExc_ValueError, "shapes must be >= 0");
        return NULL;
    }
    Py_buffer v[6];
    if (get_buffers(objs, v, 6, 3) < 0) return NULL;
    const Py_ssize_t d = (Py_ssize_t)sizeof(double);
    const Py_ssize_t bytes[6] = {S * R * G * d, S * R * 3 * d, S * R * G,
                                 S * G * 9 * d, S * G * 3 * d, S * G * d};
    PyObject *result = NULL;
    if (check_sizes(v, bytes, 6) == 0) {
        double *acc = PyMem_RawMalloc((size_t)(10 * (G > 0 ? G : 1)) * sizeof(double));
        if (acc == NULL) {
            PyErr_NoMemory();
        } else {
            Py_BEGIN_ALLOW_THREADS
            sums(v[0].buf, v[1].buf, v[2].buf, v[3].buf, v[4].buf, v[5].buf, S, R, G, acc);
            Py_END_ALLOW_THREADS
            PyMem_RawFree(acc);
            result = Py_NewRef(Py_None);
        }
    }
    release(v, 6);
    return result;
}

static PyObject *residual_ssr(PyObject *self, PyObject *args)
{
    PyObject *objs[5];
    Py_ssize_t S, R, G;
    if (!PyArg_ParseTuple(args, "OOOOOnnn", &objs[0], &objs[1], &objs[2], &objs[3], &objs[4],
                          &S, &R, &G))
        return NULL;
    if (S < 0 || R < 0 || G < 0) {
        PyErr_SetString(PyExc_ValueError, "shapes must be >= 0");
        return NULL;
    }
    Py_buffer v[5];
    if (get_buffers(objs, v, 5, 4) < 0) return NULL;
    const Py_ssize_t d = (Py_ssize_t)sizeof(double);
    const Py_ssize_t bytes[5] = {S * R * G * d, S * R * 3 * d, S * R * G, S * G * 3 * d,
                                 S * G * d};
    PyObject *result = NULL;
    if (check_sizes(v, bytes, 5) == 0) {
        double *b = PyMem_RawMalloc((size_t)(3 * (G > 0 ? G : 1)) * sizeof(double));
        if (b == NULL) {
            PyErr_NoMemory();
        } else {
            Py_BEGIN_ALLOW_THREADS
            ssr_sums(v[0].buf, v[1].buf, v[2].buf, v[3].buf, v[4].buf, S, R, G, b);
            Py_END_ALLOW_THREADS
            PyMem_RawFree(b);
            result = Py_NewRef(Py_None);
        }
    }
    release(v, 5);
    return result;
}

static PyMethodDef methods[] = {
    {"normal_sums", normal_sums, METH_VARARGS,
     "normal_sums(velocity, design, valid, ata, aty, n_rays, S, R, G): the normal "
     "equations of every (scan, gate), written to ata, aty and n_rays (see the C source)"},
    {"residual_ssr", residual_ssr, METH_VARARGS,
     "residual_ssr(velocity, design, valid, beta, ssr, S, R, G): the residual sum of "
     "squares of every (scan, gate), written to ssr (see the C source)"},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_vadsums",
                                    "Sums of the least-squares VAD fit (see the C source).",
                                    -1, methods};

PyMODINIT_FUNC PyInit__vadsums(void) { return PyModule_Create(&module); }
