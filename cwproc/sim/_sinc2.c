/*
 * Doppler spectra of a cw lidar as sums of sinc^2 on integer channels (cwproc.sim.cw).
 *
 * sum(x, a, n_spectra, n_points, n_channels, out) -> None
 *
 * out[n, k] = sum_i a[n, i] / (k - x[n, i])^2 for k = 0 .. n_channels - 1: the closed form
 * of sum_i q_i sinc^2{pi (k - x_i)} of Banakh et al. (1999), eq. 3, with
 * a_i = q_i sin^2(pi x_i) / pi^2 (cwproc.sim.cw._sinc2_sum). x, a: n_spectra * n_points
 * native doubles; out: a writable buffer of n_spectra * n_channels doubles. The
 * operations and their order are those of the numpy fallback (the same results, bit for
 * bit); a point exactly on a channel gives a non-finite total, which the caller sums
 * again with numpy's sinc. The GIL is released during the sums.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

/* the sums of one block of spectra; an AVX2 clone (4 divisions at a time) where the CPU
 * has it, chosen at load time (GCC/Clang function multiversioning), else plain C */
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__APPLE__)
__attribute__((target_clones("avx2", "default")))
#endif
static void sums(const double *restrict xs, const double *restrict as, Py_ssize_t n_spectra,
                 Py_ssize_t n_points, Py_ssize_t n_channels, const double *restrict channel,
                 double *restrict o)
{
    for (Py_ssize_t n = 0; n < n_spectra; n++) {
        double *total = o + n * n_channels;
        const double *xn = xs + n * n_points, *an = as + n * n_points;
        for (Py_ssize_t k = 0; k < n_channels; k++)
            total[k] = 0.0;
        for (Py_ssize_t i = 0; i < n_points; i++) {
            const double xi = xn[i], ai = an[i];
            for (Py_ssize_t k = 0; k < n_channels; k++) {
                const double t = channel[k] - xi;
                total[k] += ai / (t * t);
            }
        }
    }
}

static PyObject *sinc2_sum(PyObject *self, PyObject *args)
{
    Py_buffer x, a, out;
    Py_ssize_t n_spectra, n_points, n_channels;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*y*nnnw*", &x, &a, &n_spectra, &n_points, &n_channels, &out))
        return NULL;
    Py_ssize_t size = n_spectra * n_points * (Py_ssize_t)sizeof(double);
    int ok = n_spectra >= 0 && n_points >= 0 && n_channels >= 0 && x.len == size &&
             a.len == size && out.len == n_spectra * n_channels * (Py_ssize_t)sizeof(double);
    if (!ok) {
        PyBuffer_Release(&x);
        PyBuffer_Release(&a);
        PyBuffer_Release(&out);
        PyErr_SetString(PyExc_ValueError, "sum: buffer sizes do not match");
        return NULL;
    }
    const double *xs = (const double *)x.buf;
    const double *as = (const double *)a.buf;
    double *o = (double *)out.buf;
    double *channel = PyMem_RawMalloc((size_t)(n_channels > 0 ? n_channels : 1) * sizeof(double));
    if (channel == NULL) {
        PyBuffer_Release(&x);
        PyBuffer_Release(&a);
        PyBuffer_Release(&out);
        return PyErr_NoMemory();
    }
    for (Py_ssize_t k = 0; k < n_channels; k++)
        channel[k] = (double)k; /* k as a double, loaded (vectorisable) rather than converted */
    Py_BEGIN_ALLOW_THREADS
    sums(xs, as, n_spectra, n_points, n_channels, channel, o);
    Py_END_ALLOW_THREADS
    PyMem_RawFree(channel);
    PyBuffer_Release(&x);
    PyBuffer_Release(&a);
    PyBuffer_Release(&out);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"sum", sinc2_sum, METH_VARARGS,
     "sum(x, a, n_spectra, n_points, n_channels, out): out[n, k] = sum_i a / (k - x)^2"},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_sinc2",
                                    "cw Doppler spectra (Banakh et al. (1999), eq. 3)", -1,
                                    methods};

PyMODINIT_FUNC PyInit__sinc2(void) { return PyModule_Create(&module); }
