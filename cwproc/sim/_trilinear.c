/*
 * Periodic trilinear interpolation of a node-major grid (cwproc.sim.field3d).
 *
 * wrap(table, nx, ny, nz, n_comp, coords, out) -> None
 *
 * table: nx*ny*nz*n_comp native doubles, node (i, j, k) at row (i*ny + j)*nz + k, its
 * n_comp components side by side; coords: P*3 doubles, the points in units of the grid
 * spacing (any real value: the grid is periodic); out: a writable buffer of P*n_comp
 * doubles that receives the interpolated values. The scheme is that of
 * scipy.ndimage.map_coordinates(order=1, mode="grid-wrap") and of the numpy fallback
 * cwproc.sim.field3d.trilinear_wrap (same results to round-off). The GIL is released
 * while the points are interpolated, so that threads can share the work.
 *
 * radial(table, nx, ny, nz, spacing, origin, wind, beams, times, n_sweep, dist, out)
 *
 * The beam-averaged radial velocity of a frozen field carried by the wind (the inner
 * loop of cwproc.sim.pulsed.probe_averaged_velocity): for every ray r and distance d_u
 * out[r, u] = (1/J) sum_j S_rj . v(origin + S_rj d_u - wind t_rj), with v the periodic
 * trilinear interpolation of table (n_comp = 3, u v w) on a grid of the given spacing
 * (m), S_rj the unit beam vectors (R*J*3 doubles), t_rj their times (R*J, s), dist the
 * U distances along the beam (m), out R*U doubles. The points of one distance are
 * visited for all J beam positions of a ray in turn (they are close), without the GIL.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

/* rays whose points are visited distance by distance together (cache locality) */
#define RAY_BLOCK 16

static Py_ssize_t wrap_index(double floor_value, Py_ssize_t n)
{
    long long i = (long long)floor_value % (long long)n;
    return (Py_ssize_t)(i < 0 ? i + n : i);
}

static PyObject *wrap(PyObject *self, PyObject *args)
{
    Py_buffer table, coords, out;
    Py_ssize_t nx, ny, nz, nc;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*nnnny*w*", &table, &nx, &ny, &nz, &nc, &coords, &out))
        return NULL;
    Py_ssize_t n_points = coords.len / (Py_ssize_t)(3 * sizeof(double));
    int ok = nx > 0 && ny > 0 && nz > 0 && nc > 0 &&
             table.len == (Py_ssize_t)(nx * ny * nz * nc * sizeof(double)) &&
             coords.len == (Py_ssize_t)(n_points * 3 * sizeof(double)) &&
             out.len == (Py_ssize_t)(n_points * nc * sizeof(double));
    if (!ok) {
        PyBuffer_Release(&table);
        PyBuffer_Release(&coords);
        PyBuffer_Release(&out);
        PyErr_SetString(PyExc_ValueError, "wrap: buffer sizes do not match the grid");
        return NULL;
    }
    const double *t = (const double *)table.buf;
    const double *c = (const double *)coords.buf;
    double *o = (double *)out.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t p = 0; p < n_points; p++) {
        double x = c[3 * p], y = c[3 * p + 1], z = c[3 * p + 2];
        double bx = floor(x), by = floor(y), bz = floor(z);
        double fx = x - bx, fy = y - by, fz = z - bz;
        Py_ssize_t i0 = wrap_index(bx, nx), j0 = wrap_index(by, ny), k0 = wrap_index(bz, nz);
        Py_ssize_t i1 = i0 + 1 == nx ? 0 : i0 + 1;
        Py_ssize_t j1 = j0 + 1 == ny ? 0 : j0 + 1;
        Py_ssize_t k1 = k0 + 1 == nz ? 0 : k0 + 1;
        Py_ssize_t ii[2] = {i0 * ny * nz, i1 * ny * nz};
        Py_ssize_t jj[2] = {j0 * nz, j1 * nz};
        Py_ssize_t kk[2] = {k0, k1};
        double wx[2] = {1.0 - fx, fx}, wy[2] = {1.0 - fy, fy}, wz[2] = {1.0 - fz, fz};
        double *dst = o + p * nc;
        for (Py_ssize_t q = 0; q < nc; q++) dst[q] = 0.0;
        for (int a = 0; a < 2; a++) {
            for (int b = 0; b < 2; b++) {
                double wab = wx[a] * wy[b];
                for (int d = 0; d < 2; d++) {
                    double w = wab * wz[d];
                    const double *src = t + (ii[a] + jj[b] + kk[d]) * nc;
                    for (Py_ssize_t q = 0; q < nc; q++) dst[q] += w * src[q];
                }
            }
        }
    }
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&table);
    PyBuffer_Release(&coords);
    PyBuffer_Release(&out);
    Py_RETURN_NONE;
}

/* Index of the node at or below x (grid units) on a periodic axis of n nodes, and the
 * fraction of the way to the next node; the wrap costs a multiply and a floor. */
static double fast_floor(double x)
{
    double t = (double)(long long)x; /* truncation, without a call of libm's floor */
    return t > x ? t - 1.0 : t;
}

static Py_ssize_t wrap_floor(double x, Py_ssize_t n, double inv_n, double *frac)
{
    double xw = x - (double)n * fast_floor(x * inv_n); /* in [0, n] up to round-off */
    double b = fast_floor(xw);
    Py_ssize_t i = (Py_ssize_t)b;
    *frac = xw - b;
    if (i >= n) i -= n;
    if (i < 0) i += n;
    return i;
}

/* The interpolated 3-vector at a point in grid units (table of 3 components). */
static void interpolate3(const double *t, Py_ssize_t nx, Py_ssize_t ny, Py_ssize_t nz,
                         const double *inv, double x, double y, double z, double *v)
{
    double fx, fy, fz;
    Py_ssize_t i0 = wrap_floor(x, nx, inv[0], &fx);
    Py_ssize_t j0 = wrap_floor(y, ny, inv[1], &fy);
    Py_ssize_t k0 = wrap_floor(z, nz, inv[2], &fz);
    Py_ssize_t ii[2] = {i0 * ny * nz, (i0 + 1 == nx ? 0 : i0 + 1) * ny * nz};
    Py_ssize_t jj[2] = {j0 * nz, (j0 + 1 == ny ? 0 : j0 + 1) * nz};
    Py_ssize_t kk[2] = {k0, k0 + 1 == nz ? 0 : k0 + 1};
    double wx[2] = {1.0 - fx, fx}, wy[2] = {1.0 - fy, fy}, wz[2] = {1.0 - fz, fz};
    v[0] = v[1] = v[2] = 0.0;
    for (int a = 0; a < 2; a++) {
        for (int b = 0; b < 2; b++) {
            double wab = wx[a] * wy[b];
            for (int d = 0; d < 2; d++) {
                double w = wab * wz[d];
                const double *src = t + (ii[a] + jj[b] + kk[d]) * 3;
                v[0] += w * src[0];
                v[1] += w * src[1];
                v[2] += w * src[2];
            }
        }
    }
}

static PyObject *radial(PyObject *self, PyObject *args)
{
    Py_buffer table, origin, wind, beams, times, dist, out;
    Py_ssize_t nx, ny, nz, n_sweep;
    double spacing;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*nnndy*y*y*y*ny*w*", &table, &nx, &ny, &nz, &spacing,
                          &origin, &wind, &beams, &times, &n_sweep, &dist, &out))
        return NULL;
    Py_ssize_t d8 = (Py_ssize_t)sizeof(double);
    Py_ssize_t n_beams = times.len / d8, n_dist = dist.len / d8;
    Py_ssize_t n_rays = n_sweep > 0 ? n_beams / n_sweep : 0;
    int ok = nx > 0 && ny > 0 && nz > 0 && spacing > 0 && n_sweep > 0 &&
             table.len == nx * ny * nz * 3 * d8 && origin.len == 3 * d8 &&
             wind.len == 3 * d8 && beams.len == 3 * n_beams * d8 &&
             n_rays * n_sweep == n_beams && out.len == n_rays * n_dist * d8;
    if (ok) {
        const double *t = (const double *)table.buf, *o = (const double *)origin.buf;
        const double *u = (const double *)wind.buf, *s = (const double *)beams.buf;
        const double *tm = (const double *)times.buf, *dd = (const double *)dist.buf;
        double *res = (double *)out.buf;
        double inv[3] = {1.0 / (double)nx, 1.0 / (double)ny, 1.0 / (double)nz};
        double q = 1.0 / spacing;
        Py_BEGIN_ALLOW_THREADS
        /* blocks of rays, each distance for all the block's rays in turn: neighbouring
         * azimuths at one distance share grid cells (cache) out to a few hundred m */
        for (Py_ssize_t r0 = 0; r0 < n_rays; r0 += RAY_BLOCK) {
            Py_ssize_t r1 = r0 + RAY_BLOCK < n_rays ? r0 + RAY_BLOCK : n_rays;
            for (Py_ssize_t k = 0; k < n_dist; k++) {
                for (Py_ssize_t r = r0; r < r1; r++) {
                    double total = 0.0;
                    for (Py_ssize_t j = 0; j < n_sweep; j++) {
                        const double *sv = s + 3 * (r * n_sweep + j);
                        double tt = tm[r * n_sweep + j], v[3];
                        interpolate3(t, nx, ny, nz, inv, (o[0] + sv[0] * dd[k] - u[0] * tt) * q,
                                     (o[1] + sv[1] * dd[k] - u[1] * tt) * q,
                                     (o[2] + sv[2] * dd[k] - u[2] * tt) * q, v);
                        total += sv[0] * v[0] + sv[1] * v[1] + sv[2] * v[2];
                    }
                    res[r * n_dist + k] = total / (double)n_sweep;
                }
            }
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&table);
    PyBuffer_Release(&origin);
    PyBuffer_Release(&wind);
    PyBuffer_Release(&beams);
    PyBuffer_Release(&times);
    PyBuffer_Release(&dist);
    PyBuffer_Release(&out);
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "radial: buffer sizes do not match");
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"radial", radial, METH_VARARGS,
     "radial(table, nx, ny, nz, spacing, origin, wind, beams, times, n_sweep, dist, out): "
     "sweep-averaged radial velocity of a frozen field along beams."},
    {"wrap", wrap, METH_VARARGS,
     "wrap(table, nx, ny, nz, n_comp, coords, out): periodic trilinear interpolation."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_trilinear",
                                    "Periodic trilinear interpolation (cwproc.sim.field3d).",
                                    -1, methods};

PyMODINIT_FUNC PyInit__trilinear(void) { return PyModule_Create(&module); }
