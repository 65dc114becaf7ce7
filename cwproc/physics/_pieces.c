/*
 * Piecewise polynomials of the A-table build at scattered points (cwproc.physics).
 *
 * bicubic(coef, knots_x, knots_y, lookup_x, lookup_y, grid, x, y, out) -> None
 *
 * The bicubic spline of cwproc.physics.atable_swept.BicubicPieces at the points (x[i],
 * y[i]): coef holds the cells' power-basis coefficients cell by cell (cells * 16
 * doubles, coefficient of du^p dv^q at p * 4 + q, cell i * (ny - 1) + j of the ny
 * distinct knots_y); the cell of a point is found on the uniform data grids, grid =
 * (x0, scale_x, y0, scale_y) with scale = (nodes - 1) / (last - first) and lookup_x,
 * lookup_y (intp) the knot interval of each grid interval. out: a writable buffer of
 * the points' doubles.
 *
 * plane(coef, knots_x, knots_y, lookup_x, lookup_y, grid, ends, log_s, angle, out)
 *
 * log A of cwproc.physics.atable_swept.PlaneCurves: the spline at (clip(log_s, lo, hi),
 * 1 - sqrt(clip(1 - 2 angle / pi, 0, 1))) with angle = arctan2(s_par, s_perp), and
 * below lo the straight line through the values at lo and l1 (ends = (lo, hi, l1)).
 *
 * cubic_stack(coef, knots, scale, n_curves, ends, log_rho, out) -> None
 *
 * Cubic splines on the same uniform knots (cwproc.physics.curve_kernel.CurveStack) at
 * the points log_rho: coef n_curves * cells * 4 doubles (powers 3, 2, 1, 0 of the
 * offset from the cell's left knot), scale = cells / (last - first knot), ends
 * n_curves * 4 doubles (value and slope of the straight lines below the first and
 * beyond the last knot), out n_curves * points doubles.
 *
 * The operations and their order are those of the numpy fallbacks (Horner sums, the
 * cell by floor and clip), without contraction to fused multiply-adds: the same
 * results, bit for bit (tested). The GIL is released during the sums.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

static const double PI = 3.141592653589793; /* numpy.pi */

/* the interval of at on a uniform grid of n_intervals, clipped to the ends: numpy's
 * clip(floor(t), 0, n - 1) (t < 0 and NaN give 0), by truncation (no call of floor) */
static Py_ssize_t interval(double at, double first, double scale, Py_ssize_t n_intervals)
{
    double t = (at - first) * scale;
    if (!(t >= 0.0))
        return 0;
    if (t >= (double)n_intervals)
        return n_intervals - 1;
    return (Py_ssize_t)t;
}

typedef struct {
    const double *coef;
    const double *u, *v;
    const Py_ssize_t *lx, *ly;
    Py_ssize_t ngx, ngy, nv;
    double x0, sx, y0, sy;
} Bicubic;

static double bicubic_at(const Bicubic *b, double x, double y)
{
    Py_ssize_t i = b->lx[interval(x, b->x0, b->sx, b->ngx - 1)];
    Py_ssize_t j = b->ly[interval(y, b->y0, b->sy, b->ngy - 1)];
    double du = x - b->u[i], dv = y - b->v[j];
    const double *c = b->coef + 16 * (i * (b->nv - 1) + j);
    double out = 0.0;
    for (int q = 3; q >= 0; q--) { /* Horner in dv of the Horner sums in du */
        double row = ((c[12 + q] * du + c[8 + q]) * du + c[4 + q]) * du;
        row = row + c[q];
        out = q == 3 ? row : out * dv + row;
    }
    return out;
}

/* parses the spline's buffers (9 objects) into b; 0 and an exception on a mismatch */
static int parse_bicubic(Bicubic *b, Py_buffer *buf, PyObject *grid)
{
    Py_ssize_t nu = buf[1].len / (Py_ssize_t)sizeof(double);
    Py_ssize_t nv = buf[2].len / (Py_ssize_t)sizeof(double);
    Py_ssize_t ngx = buf[3].len / (Py_ssize_t)sizeof(Py_ssize_t) + 1;
    Py_ssize_t ngy = buf[4].len / (Py_ssize_t)sizeof(Py_ssize_t) + 1;
    if (!PyArg_ParseTuple(grid, "dddd", &b->x0, &b->sx, &b->y0, &b->sy))
        return 0;
    if (nu < 2 || nv < 2 || ngx < 2 || ngy < 2 ||
        buf[0].len != (Py_ssize_t)((nu - 1) * (nv - 1) * 16 * sizeof(double))) {
        PyErr_SetString(PyExc_ValueError, "bicubic: buffer sizes do not match the spline");
        return 0;
    }
    const Py_ssize_t *lx = (const Py_ssize_t *)buf[3].buf, *ly = (const Py_ssize_t *)buf[4].buf;
    for (Py_ssize_t k = 0; k < ngx - 1; k++)
        if (lx[k] < 0 || lx[k] > nu - 2) {
            PyErr_SetString(PyExc_ValueError, "bicubic: lookup_x outside the knots");
            return 0;
        }
    for (Py_ssize_t k = 0; k < ngy - 1; k++)
        if (ly[k] < 0 || ly[k] > nv - 2) {
            PyErr_SetString(PyExc_ValueError, "bicubic: lookup_y outside the knots");
            return 0;
        }
    b->coef = (const double *)buf[0].buf;
    b->u = (const double *)buf[1].buf;
    b->v = (const double *)buf[2].buf;
    b->lx = lx;
    b->ly = ly;
    b->ngx = ngx;
    b->ngy = ngy;
    b->nv = nv;
    return 1;
}

static void release(Py_buffer *buf, int n)
{
    for (int k = 0; k < n; k++)
        PyBuffer_Release(&buf[k]);
}

static PyObject *bicubic(PyObject *self, PyObject *args)
{
    Py_buffer buf[8];
    PyObject *grid;
    Bicubic b;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*y*y*y*y*Oy*y*w*", &buf[0], &buf[1], &buf[2], &buf[3],
                          &buf[4], &grid, &buf[5], &buf[6], &buf[7]))
        return NULL;
    Py_ssize_t n = buf[5].len / (Py_ssize_t)sizeof(double);
    if (!parse_bicubic(&b, buf, grid)) {
        release(buf, 8);
        return NULL;
    }
    if (buf[6].len != buf[5].len || buf[7].len != buf[5].len) {
        release(buf, 8);
        PyErr_SetString(PyExc_ValueError, "bicubic: x, y and out differ in size");
        return NULL;
    }
    const double *x = (const double *)buf[5].buf, *y = (const double *)buf[6].buf;
    double *o = (double *)buf[7].buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t k = 0; k < n; k++)
        o[k] = bicubic_at(&b, x[k], y[k]);
    Py_END_ALLOW_THREADS
    release(buf, 8);
    Py_RETURN_NONE;
}

static PyObject *plane(PyObject *self, PyObject *args)
{
    Py_buffer buf[8];
    PyObject *grid;
    double lo, hi, l1;
    Bicubic b;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*y*y*y*y*O(ddd)y*y*w*", &buf[0], &buf[1], &buf[2], &buf[3],
                          &buf[4], &grid, &lo, &hi, &l1, &buf[5], &buf[6], &buf[7]))
        return NULL;
    Py_ssize_t n = buf[5].len / (Py_ssize_t)sizeof(double);
    if (!parse_bicubic(&b, buf, grid)) {
        release(buf, 8);
        return NULL;
    }
    if (buf[6].len != buf[5].len || buf[7].len != buf[5].len) {
        release(buf, 8);
        PyErr_SetString(PyExc_ValueError, "plane: log_s, angle and out differ in size");
        return NULL;
    }
    const double *ls = (const double *)buf[5].buf, *angle = (const double *)buf[6].buf;
    double *o = (double *)buf[7].buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t k = 0; k < n; k++) {
        double t = 1.0 - 2.0 * angle[k] / PI; /* numpy: 1.0 - ((2.0 * a) / pi) */
        t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
        double beta = 1.0 - sqrt(t);
        double l = ls[k];
        double at = l < lo ? lo : (l > hi ? hi : l);
        double val = bicubic_at(&b, at, beta);
        if (l < lo) { /* the power law in s below the grid */
            double second = bicubic_at(&b, l1, beta);
            double slope = (second - val) / (l1 - lo);
            val = val + slope * (l - lo);
        }
        o[k] = val;
    }
    Py_END_ALLOW_THREADS
    release(buf, 8);
    Py_RETURN_NONE;
}

static PyObject *cubic_stack(PyObject *self, PyObject *args)
{
    Py_buffer buf[5]; /* coef, knots, ends, points, out */
    double scale;
    Py_ssize_t n_curves;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*y*dny*y*w*", &buf[0], &buf[1], &scale, &n_curves, &buf[2],
                          &buf[3], &buf[4]))
        return NULL;
    Py_ssize_t n = buf[3].len / (Py_ssize_t)sizeof(double);
    Py_ssize_t n_cells = buf[1].len / (Py_ssize_t)sizeof(double) - 1;
    int ok = n_cells > 0 && n_curves > 0 &&
             buf[0].len == (Py_ssize_t)(n_curves * n_cells * 4 * sizeof(double)) &&
             buf[2].len == (Py_ssize_t)(n_curves * 4 * sizeof(double)) &&
             buf[4].len == (Py_ssize_t)(n_curves * n * sizeof(double));
    if (!ok) {
        release(buf, 5);
        PyErr_SetString(PyExc_ValueError, "cubic_stack: buffer sizes do not match");
        return NULL;
    }
    const double *c = (const double *)buf[0].buf, *knots = (const double *)buf[1].buf;
    const double *e = (const double *)buf[2].buf, *x = (const double *)buf[3].buf;
    double *o = (double *)buf[4].buf;
    double first = knots[0], last = knots[n_cells];
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t k = 0; k < n; k++) {
        double at = x[k];
        Py_ssize_t cell = interval(at, first, scale, n_cells);
        double d = at - knots[cell];
        const double *cm = c + 4 * cell;
        for (Py_ssize_t m = 0; m < n_curves; m++, cm += 4 * n_cells) {
            const double *em = e + 4 * m;
            double val;
            if (at < first)
                val = em[0] + em[1] * (at - first);
            else if (at > last)
                val = em[2] + em[3] * (at - last);
            else
                val = ((cm[0] * d + cm[1]) * d + cm[2]) * d + cm[3];
            o[m * n + k] = val;
        }
    }
    Py_END_ALLOW_THREADS
    release(buf, 5);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"bicubic", bicubic, METH_VARARGS,
     "bicubic(coef, knots_x, knots_y, lookup_x, lookup_y, grid, x, y, out)"},
    {"plane", plane, METH_VARARGS,
     "plane(coef, knots_x, knots_y, lookup_x, lookup_y, grid, ends, log_s, angle, out)"},
    {"cubic_stack", cubic_stack, METH_VARARGS,
     "cubic_stack(coef, knots, scale, n_curves, ends, log_rho, out)"},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_pieces",
                                    "piecewise polynomials of the A-table build", -1, methods};

PyMODINIT_FUNC PyInit__pieces(void) { return PyModule_Create(&module); }
