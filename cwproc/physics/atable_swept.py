"""A_2 of the swept rays of a continuous scan, seen at their own times (A-tables).

A continuous scan accumulates each ray while the beam sweeps one azimuth step ``dy``
and the mean wind ``U = mu V_s`` carries the frozen field; sub-beam ``f`` of a ray
(``f`` in ``[0, 1)``) is seen ``f tau`` later, ``tau`` the ray period, so in the frozen
field the ray averages along ``dy (e_scan - mu e_wind)``, and two rays ``l`` steps apart
are separated by ``l`` times the same vector. Every pair of sub-beams is therefore a
step-stare pair at the fractional lag ``x = l + f_a - f_b`` and, with ``D0(x)`` the
structure function of step-stare rays,

``D_swept(l) = int tri(x - l) D0(x) dx - 2 int_0^1 (1 - x) D0(x) dx``,

``tri(u) = max(0, 1 - |u|)`` (the second term is the two rays' own averaging; exact for
frozen turbulence, up to the shift of the pair's mean azimuth by a fraction of a step).
:func:`sweep_kernel` is this as a quadrature over ``x``.

``D0`` is the small-angle structure function of two range-weighted rays, which depends
on the separation's components along the beam and across it
(:func:`cwproc.physics.afunctions.a_plane`, tabulated by :func:`plane_curves`): the
horizontal separation ``x dy (a, b)``, ``a = 1 - mu sin th`` across and ``b = mu cos th``
along the horizontal beam, has ``x dy b cos(phi)`` along the beam and ``x dy sqrt(a^2 +
b^2 sin^2 phi)`` across it. Smalikho (2020), eq. 15 mixes ``A_perp`` and ``A_par`` of
the whole length instead, which is exact for a point probe only; with the Stream Line
gate and separations of a few metres (2-5 deg steps at 100 m) it is 5-20 % low where
the wind shortens the separation along the scan (``mu`` ~ 1). The beams of a pair are
not parallel: at the mean range offset ``v`` of a pair of probe points their horizontal
separation across the beam is ``x dy (a + v / R)`` (:func:`offset_rule`, three
Gauss-Hermite nodes of the pair rule's variance of ``v``), which keeps ``D0`` finite where
the wind cancels the scan (``a = b = 0``). The remaining geometry of the pair (chord,
angle between the beams) is the exact point-probe pair minus eq. 15 of the point
(:func:`point_difference`, on the circle ``R' = 1`` where both scale as ``R'^(2/3)``),
acting on the cross term ``D0 + 2S`` (``2S`` the same-beam term) as in
:func:`cwproc.physics.atable.geometry_correction`, relative to eq. 15 of the point
averaged over ``v``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.polynomial import legendre

from cwproc.physics import afunctions, two_beam

try:  # optional C extension (setup.py): the splines' sums, the same numbers bit for bit
    from cwproc.physics import _pieces
except ImportError:  # pragma: no cover - depends on the build
    _pieces = None

#: whether the splines use the C extension when it is built (tests compare both)
_use_extension = True

#: Gauss-Legendre nodes of the sweep kernel per unit of fractional lag
SWEEP_NODES = 6
#: Gauss-Legendre nodes per unit of fractional lag of :func:`difference_kernel`
DIFFERENCE_NODES = 3
#: angle nodes (0 to 90 deg from across the beam) of :func:`plane_curves`
N_ANGLE = 17
#: separation nodes per decade of :func:`plane_curves`
PLANE_PER_DECADE = 10


@dataclass(frozen=True)
class PlaneCurves:
    """``log A(s, beta)`` of :func:`cwproc.physics.afunctions.a_plane` on a grid.

    ``s`` the separation (m), ``beta`` its angle from the plane across the beam
    (``s_par = s sin beta``); bicubic spline in ``(log s, c)``, ``c`` of
    :func:`_angle_coordinate` (``angle`` holds its nodes), a power law in ``s`` below the
    grid (per angle, from its first two nodes).
    """

    log_s: np.ndarray
    angle: np.ndarray
    log_a: np.ndarray

    def __call__(self, s_par: np.ndarray, s_perp: np.ndarray) -> np.ndarray:
        """``A`` (m^(2/3)) at separations ``s_par`` along and ``s_perp`` across the beam."""
        s_par, s_perp = np.abs(s_par), np.abs(s_perp)
        angle = np.arctan2(s_par, s_perp)
        ls = 0.5 * np.log(np.maximum(s_par * s_par + s_perp * s_perp, 1e-300))
        out = np.exp(self.pieces().plane(ls, angle, self.log_s[1]))
        zero = (s_par == 0) & (s_perp == 0)
        if zero.any():
            out[zero] = 0.0
        return out

    def pieces(self) -> BicubicPieces:
        """The interpolating bicubic spline of ``log_a`` as :class:`BicubicPieces` (kept)."""
        cached = self.__dict__.get("_pieces")
        if cached is None:
            cached = BicubicPieces.of(self.log_s, self.angle, self.log_a)
            object.__setattr__(self, "_pieces", cached)
        return cached


@dataclass(frozen=True)
class BicubicPieces:
    """A bicubic spline as polynomials per cell, evaluated at scattered points.

    The interpolating spline of :class:`scipy.interpolate.RectBivariateSpline` (``s = 0``,
    not-a-knot ends) in the local power basis: ``sum_pq c[i, j, p, q] du^p dv^q`` on cell
    ``(i, j)`` between the distinct knots ``u[i]``, ``v[j]``. Equal to its ``ev`` within
    rounding (1e-13 relative on ``log A``, tested); in numpy about 5x faster on the 3e5
    points of a height of swept pairs (``ev`` calls FITPACK point by point), by the
    optional C extension ``cwproc.physics._pieces`` another 5x (the same numbers, bit
    for bit).
    """

    u: np.ndarray
    v: np.ndarray
    coef: np.ndarray  # (4, 4, cells): power of du, power of dv, cell i * (v.size - 1) + j
    grid_x: np.ndarray  # the uniform data grids (the knots are among their nodes)
    grid_y: np.ndarray

    @classmethod
    def of(cls, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> BicubicPieces:
        """The pieces of the interpolating spline of ``z`` on the grid ``(x, y)``."""
        from scipy import interpolate  # here: with scipy.optimize, 0.1 s of imports

        for grid in (x, y):  # the cells are found by the grid step (_cell)
            if not np.allclose(np.diff(grid), grid[1] - grid[0], rtol=1e-9, atol=0):
                raise ValueError("BicubicPieces needs uniform grids")
        spline = interpolate.RectBivariateSpline(x, y, z)
        tx, ty, c = spline.tck  # full knot vectors (ends repeated 4 times)
        c = c.reshape(tx.size - 4, ty.size - 4)
        u, cu = _power_basis(tx, interpolate)
        v, cv = _power_basis(ty, interpolate)
        coef = np.einsum("api,ij,bqj->pqab", cu, c, cv)
        return cls(u, v, np.ascontiguousarray(coef.reshape(4, 4, -1)), x, y)

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The spline at the points ``(x, y)`` (any shape, inside the grid).

        By the C extension ``cwproc.physics._pieces`` when it is built (same operations
        in the same order: the same numbers, bit for bit, tested), else :meth:`numpy_at`.
        """
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        if _pieces is None or not _use_extension:
            return self.numpy_at(x, y)
        out = np.empty(x.shape)
        x, y = np.ascontiguousarray(x), np.ascontiguousarray(y)
        _pieces.bicubic(*self._compiled(), x, y, out)
        return out

    def plane(self, log_s: np.ndarray, angle: np.ndarray, log_s1: float) -> np.ndarray:
        """``log A`` of :class:`PlaneCurves` at ``log s`` and ``arctan2(s_par, s_perp)``.

        The spline at ``(clip(log_s), c)`` (``c`` of :func:`_angle_coordinate`) and below
        the first grid node the straight line through its values there and at ``log_s1``
        (the second node): a power law in ``s``. By the C extension when built (bit for
        bit the numpy path, tested).
        """
        log_s, angle = np.broadcast_arrays(
            np.asarray(log_s, dtype=float), np.asarray(angle, dtype=float)
        )
        lo, hi = float(self.grid_x[0]), float(self.grid_x[-1])
        if _pieces is None or not _use_extension:
            beta = _angle_coordinate(angle)
            val = self.numpy_at(np.clip(log_s, lo, hi), beta)
            below = log_s < lo
            if below.any():
                first = val[below]
                second = self.numpy_at(np.full(first.shape, log_s1), beta[below])
                slope = (second - first) / (log_s1 - lo)
                val[below] = first + slope * (log_s[below] - lo)
            return val
        out = np.empty(log_s.shape)
        log_s, angle = np.ascontiguousarray(log_s), np.ascontiguousarray(angle)
        _pieces.plane(*self._compiled(), (lo, hi, float(log_s1)), log_s, angle, out)
        return out

    def _compiled(self) -> tuple:
        """The arguments of the C kernels that describe the spline (kept)."""
        cached = self.__dict__.get("_args")
        if cached is None:
            cells = np.ascontiguousarray(self.coef.reshape(16, -1).T)  # (cells, p * 4 + q)
            grid = tuple(float(v) for v in (*_grid_scale(self.grid_x), *_grid_scale(self.grid_y)))
            lookup_x = np.ascontiguousarray(_lookup(self.u, self.grid_x), dtype=np.intp)
            lookup_y = np.ascontiguousarray(_lookup(self.v, self.grid_y), dtype=np.intp)
            cached = (cells, self.u, self.v, lookup_x, lookup_y, grid)
            object.__setattr__(self, "_args", cached)
        return cached

    def numpy_at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The spline at the points ``(x, y)`` in numpy (the reference of the C kernel)."""
        i, j = _cell(self.u, self.grid_x, x), _cell(self.v, self.grid_y, y)
        du, dv = x - self.u[i], y - self.v[j]
        cell = i * (self.v.size - 1) + j
        out = None
        for q in (3, 2, 1, 0):  # Horner in dv of the Horner sums in du
            c = self.coef[:, q]
            row = ((c[3].take(cell) * du + c[2].take(cell)) * du + c[1].take(cell)) * du
            row += c[0].take(cell)
            out = row if out is None else out * dv + row
        return out


def _grid_scale(grid: np.ndarray) -> tuple[float, float]:
    """First node and ``(nodes - 1) / (last - first)`` of a uniform grid."""
    return grid[0], (grid.size - 1) / (grid[-1] - grid[0])


def _lookup(knots: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """The knot interval of each interval of the uniform ``grid`` (the knots are nodes)."""
    return np.clip(np.searchsorted(knots, grid[:-1], side="right") - 1, 0, knots.size - 2)


def _cell(knots: np.ndarray, grid: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Index of the knot interval of ``at`` (clipped to the ends) via the uniform ``grid``.

    Arithmetic on the grid step (a binary search per point cost 40 % of the evaluation);
    at a knot, rounding may pick the neighbouring interval, whose polynomial agrees
    there to rounding (the spline is C2).
    """
    first, scale = _grid_scale(grid)
    k = np.floor((at - first) * scale)
    k = np.clip(k, 0, grid.size - 2).astype(np.intp)
    return _lookup(knots, grid).take(k)


def _power_basis(t: np.ndarray, interpolate: Any) -> tuple[np.ndarray, np.ndarray]:
    """Distinct knots ``u`` and ``B_i^(p)(u_m) / p!``, ``(cells, 4, basis)``, of cubic B-splines."""
    u = np.unique(t)
    basis = interpolate.BSpline(t, np.eye(t.size - 4), 3)
    left = u[:-1]
    parts = [basis(left)] + [basis.derivative(p)(left) / math.factorial(p) for p in (1, 2, 3)]
    return u, np.stack(parts, axis=1)


def plane_curves(probe: Any, range_m: float, s_min: float, s_max: float) -> PlaneCurves:
    """:class:`PlaneCurves` of the inertial model over ``[s_min, s_max]`` (m).

    :data:`PLANE_PER_DECADE` separations per decade, :data:`N_ANGLE` angles; relative
    interpolation error below 5e-4 (4.2e-4 measured at 1000 random points,
    tested against direct evaluation).
    """
    n = max(8, math.ceil(PLANE_PER_DECADE * math.log10(s_max / s_min)) + 1)
    s = np.geomspace(s_min, s_max, n)
    angle = np.linspace(0.0, 1.0, N_ANGLE)
    beta = 0.5 * np.pi * (1.0 - (1.0 - angle) ** 2)  # inverse of _angle_coordinate
    ss, bb = np.meshgrid(s, beta, indexing="ij")
    # along the beam exactly (cos(pi/2) = 6e-17 in floating point would stretch the
    # wavenumber panels of a_plane to 1e20 per metre and double its cost: 4e-7 relative)
    across = np.where(bb == 0.5 * np.pi, 0.0, np.cos(bb))
    values = afunctions.a_plane(ss * np.sin(bb), ss * across, probe=probe, range_m=range_m)
    return PlaneCurves(np.log(s), angle, np.log(values))


def _angle_coordinate(beta: np.ndarray) -> np.ndarray:
    """``1 - sqrt(1 - 2 beta / pi)``: nodes dense towards the beam (``beta = pi/2``).

    Across the beam the range weighting filters nothing, so ``A`` varies with the
    transverse part ``s cos(beta)`` as ``|s cos(beta)|^(5/3)`` near ``beta = pi/2``; in
    this coordinate that is ``(1 - c)^(10/3)``, smooth enough for the cubic spline.
    """
    return 1.0 - np.sqrt(np.clip(1.0 - 2.0 * np.asarray(beta) / np.pi, 0.0, 1.0))


def sweep_kernel(lags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nodes ``x`` (fractional lags) and weights ``K (lags, x)``: ``D_swept = K @ D0(x)``.

    Gauss-Legendre, :data:`SWEEP_NODES` per unit of ``x`` on ``[0, max(lags) + 1]``,
    graded as ``x = t^3`` on ``[0, 1]`` where ``D0 ~ x^(2/3)`` has its cusp.
    """
    lags = np.asarray(lags, dtype=float)
    t, w = legendre.leggauss(SWEEP_NODES)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    xs, ws = [t**3], [3.0 * t**2 * w]
    for k in range(1, int(lags.max()) + 1):
        xs.append(k + t)
        ws.append(w)
    x, w = np.concatenate(xs), np.concatenate(ws)
    tri = np.clip(1.0 - np.abs(x[None, :] - lags[:, None]), 0.0, None)
    own = 2.0 * np.clip(1.0 - x, 0.0, None)[None, :]
    return x, (tri - own) * w[None, :]


def difference_kernel(lags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sweep_kernel` for a smooth ``D0``: :data:`DIFFERENCE_NODES` per unit of ``x``.

    The finite outer scale's part of ``D0`` (a model's structure function less the
    inertial one, Smalikho (2020), eq. 15 of the same probe) has no cusp at ``x = 0``
    (it starts as ``x^2``), so ungraded Gauss-Legendre nodes on each unit interval
    (the kinks of ``tri`` are their ends) integrate ``D_swept = K @ D0(x)`` to about
    1e-5 of that part (5 deg steps at 60-225 m, ``mu`` 0-6, ``L_V`` 150 m, against the
    graded :func:`sweep_kernel`).
    """
    lags = np.asarray(lags, dtype=float)
    t, w = legendre.leggauss(DIFFERENCE_NODES)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    units = int(lags.max()) + 1
    x = np.concatenate([k + t for k in range(units)])
    w = np.tile(w, units)
    tri = np.clip(1.0 - np.abs(x[None, :] - lags[:, None]), 0.0, None)
    own = 2.0 * np.clip(1.0 - x, 0.0, None)[None, :]
    return x, (tri - own) * w[None, :]


def stare_kernel(lags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of step-stare rays: the lags themselves, ``D = D0(l)``.

    A step-stare ray is seen with the beam at rest, so the pair ``l`` steps apart is
    the pair at the whole lag ``l`` (no sweep average, Smalikho (2020), eq. 15 with
    ``H_perp = 1``): the identity in the form of :func:`sweep_kernel`.
    """
    lags = np.asarray(lags, dtype=float)
    return lags.copy(), np.eye(lags.size)


def dwell_kernel(lags: np.ndarray, dwell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes ``(x_scan, x_wind)`` and weights ``K (lags, nodes)`` of step-stare rays with dwell.

    A step-stare ray holds its azimuth for the dwell ``T_d = d tau`` (pulses per ray
    over the pulse repetition rate; ``tau`` the ray period) while the wind carries the
    frozen field: sub-beam ``f`` in ``[0, d)`` of ray ``l`` sees the field at ``l dy e_scan
    - (l + f) mu dy e_wind``. Two sub-beams are then the pair of beams ``x_scan = l``
    steps apart whose field moved ``x_wind = l + f_a - f_b`` ray periods, and

    ``D(l) = int tri_d(u) D0(l, l + u) du - int tri_d(u) D0(0, u) du``,

    ``tri_d(u) = (d - |u|) / d^2`` on ``[-d, d]`` (the density of ``u = f_a - f_b``; the
    second term is the rays' own averaging, as in :func:`sweep_kernel`, where ``x_scan =
    x_wind``). Gauss-Legendre, :data:`SWEEP_NODES` on each half of ``u`` per lag (the
    kink of ``tri_d`` at 0 is a node boundary), graded as ``u = d t^3`` for the own term
    whose ``D0(0, u) ~ u^(2/3)`` has its cusp at 0 (even in ``u``: one half, doubled).
    ``d = 0`` is :func:`stare_kernel` (instantaneous rays) exactly.

    Returns
    -------
    x_scan, x_wind, weights : numpy.ndarray
        ``(nodes,)``, ``(nodes,)``, ``(lags, nodes)``.
    """
    lags = np.asarray(lags, dtype=float)
    dwell = float(dwell)
    if not 0.0 <= dwell <= 1.0:
        raise ValueError(f"the dwell fraction must be in [0, 1], got {dwell!r}")
    if dwell == 0.0:
        x, weights = stare_kernel(lags)
        return x, x.copy(), weights
    t, w = legendre.leggauss(SWEEP_NODES)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    half = np.concatenate([-dwell * t, dwell * t])  # u on [-d, 0] and [0, d]
    tri = np.concatenate([w, w]) * (dwell - np.abs(half)) / dwell  # du tri_d(u)
    own_u = dwell * t**3
    own = -2.0 * (dwell - own_u) / dwell * 3.0 * t**2 * w
    n, k = lags.size, half.size
    x_scan = np.concatenate([np.repeat(lags, k), np.zeros(t.size)])
    x_wind = np.concatenate([(lags[:, None] + half[None, :]).ravel(), own_u])
    weights = np.zeros((n, x_scan.size))
    for i in range(n):
        weights[i, i * k : (i + 1) * k] = tri
    weights[:, n * k :] = own[None, :]
    return x_scan, x_wind, weights


def dwell_difference_kernel(
    lags: np.ndarray, dwell: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`dwell_kernel` for a smooth ``D0``: three nodes of ``tri_d`` per lag, one own.

    The finite outer scale's part of ``D0`` (eq. 15's difference of a model's and the
    inertial curves, Smalikho (2020)) is smooth in the separation (it starts as its
    square), so ``int tri_d(u) D0(l, l + u) du`` takes the three-point rule of the
    density ``tri_d`` itself: ``u = 0``, ``+-d sqrt(2/5)`` with weights 14/24, 5/24,
    5/24 (its moments 1, ``d^2/6``, ``d^4/15``: exact for polynomials of ``u`` up to
    degree 5), and the own term, even in ``u`` and zero at ``u = 0``, the node ``u = d
    sqrt(2/5)`` with weight 10/24 (``D0(0, 0) = 0`` left out). The von Kármán table's
    ``log A_2`` is within 2e-4 of the graded rule of :func:`dwell_kernel` at ``L_V`` >=
    170 m and 1e-3 at 80 m (36 rays, ``d`` 0.75, ``mu`` <= 3, h 80-125 m), with a
    third of its nodes.
    """
    lags = np.asarray(lags, dtype=float)
    dwell = float(dwell)
    if not 0.0 <= dwell <= 1.0:
        raise ValueError(f"the dwell fraction must be in [0, 1], got {dwell!r}")
    if dwell == 0.0:
        x, weights = stare_kernel(lags)
        return x, x.copy(), weights
    s = dwell * math.sqrt(0.4)
    u = np.array([-s, 0.0, s])
    tri = np.array([5.0, 14.0, 5.0]) / 24.0
    n = lags.size
    x_scan = np.concatenate([np.repeat(lags, 3), [0.0]])
    x_wind = np.concatenate([(lags[:, None] + u[None, :]).ravel(), [s]])
    weights = np.zeros((n, x_scan.size))
    for i in range(n):
        weights[i, 3 * i : 3 * i + 3] = tri
    weights[:, -1] = -10.0 / 24.0
    return x_scan, x_wind, weights


def kernel_nodes(
    kernel: tuple[np.ndarray, ...],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x_scan, x_wind, weights)`` of a kernel: a swept or stare one has ``x_wind = x``."""
    if len(kernel) == 2:
        x, weights = kernel
        return x, x, weights
    return kernel[0], kernel[1], kernel[2]


def offset_rule(probe: Any, range_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes ``v / R`` and weights of the mean range offset ``v`` of a pair of probe points.

    Three Gauss-Hermite nodes (``0``, ``+-sqrt(3) sigma_v``; weights 2/3, 1/6, 1/6) with
    ``sigma_v^2`` the variance of ``v = (z_a + z_b)/2 - R`` under the pair rule of
    :func:`cwproc.physics.two_beam.beam_quadrature`.
    """
    q = two_beam.beam_quadrature(probe, range_m)
    v = 0.5 * (q.z_a + q.z_b) - range_m
    sigma = math.sqrt(float(np.sum(q.weights * v * v)))
    nodes = np.array([-math.sqrt(3.0), 0.0, math.sqrt(3.0)]) * sigma / range_m
    return nodes, np.array([1.0, 4.0, 1.0]) / 6.0


def _components(mu: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a = 1 - mu sin th`` (across) and ``b = mu cos th`` (along), ``(mu, theta)``."""
    mu = np.asarray(mu, float)[:, None]
    return 1.0 - mu * np.sin(theta)[None, :], mu * np.cos(theta)[None, :]


def _point_eq15(a: np.ndarray, b: np.ndarray, phi_deg: float) -> np.ndarray:
    """Smalikho (2020), eq. 15 integrand of a point probe per ``(x dtheta)^(2/3)``.

    ``g^(1/3) [(8/3) - (2/3) cos^2(phi) b^2 / g]``, ``g = a^2 + b^2`` (``A_perp = (8/3)
    r^(2/3)``, ``A_par = 2 r^(2/3)``).
    """
    g = a * a + b * b
    c2 = math.cos(math.radians(phi_deg)) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        along = np.where(g > 0, c2 * b * b / np.where(g > 0, g, 1.0), 0.0)
    return np.cbrt(g) * (8.0 / 3.0 - (2.0 / 3.0) * along)


def point_pair(
    phi_deg: float,
    delta_theta_deg: float,
    x: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    radius: float,
    x_wind: np.ndarray | None = None,
) -> np.ndarray:
    """Exact inertial point pair (per eps^(2/3)) on the circle ``R' = 1``, ``(x, mu, theta)``.

    Points at ``radius`` (relative to ``R'``) on beams ``x dtheta`` apart, centred on north
    and scanning towards east, the transport ``(a, b)``: ``a = 1 - mu sin th`` across,
    ``b = mu cos th`` along the horizontal beam, over ``x_wind`` ray periods (``x`` when
    ``None``: a swept pair; ray period ``dtheta``, ``V_s = 1``).
    ``D = r^(2/3) [(8/3) S_a.S_b - (2/3) (S_a.r)(S_b.r)/r^2]`` (the inertial structure
    tensor, Banakh et al. (1999), eq. 16; as
    :func:`cwproc.physics.two_beam.cross_term` for a point).
    """
    x_wind = x if x_wind is None else x_wind
    step = math.radians(delta_theta_deg)
    cphi, sphi = math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))
    half = 0.5 * x * step
    # unit beams (up, north, east) at azimuths -half (a, earlier) and +half (b)
    sa = (sphi, cphi * np.cos(half), -cphi * np.sin(half))
    sb = (sphi, cphi * np.cos(half), cphi * np.sin(half))
    # separation x_a - x_b + U x_wind dtheta: across (east) and along (north) the beam
    moved = (x_wind * step)[:, None, None]
    east = (-2.0 * radius * np.sin(half))[:, None, None] + moved * (1.0 - a)
    north = moved * b[None]
    r2 = east**2 + north**2
    dot = (sphi * sphi + (cphi * cphi) * np.cos(2.0 * half))[:, None, None]
    pa = sa[1][:, None, None] * north + sa[2][:, None, None] * east
    pb = sb[1][:, None, None] * north + sb[2][:, None, None] * east
    with np.errstate(invalid="ignore", divide="ignore"):
        proj = np.where(r2 > 0, pa * pb / np.where(r2 > 0, r2, 1.0), 0.0)
    return np.cbrt(r2) * ((8.0 / 3.0) * dot - (2.0 / 3.0) * proj)


def _across(
    x: np.ndarray,
    mu: np.ndarray,
    theta: np.ndarray,
    shift: float,
    step: float,
    x_wind: np.ndarray | None = None,
) -> np.ndarray:
    """Horizontal separation across the beam per ``dy``, ``(x, mu, theta)``.

    The chord of beams ``x`` steps apart at radius ``1 + shift`` (``2 sin(x dtheta/2)``,
    relative to ``R'``) less the wind's component along the scan over ``x_wind`` ray
    periods (``x`` when ``None``), ``x_wind mu sin th`` steps.
    """
    x_wind = x if x_wind is None else x_wind
    chord = x * np.sinc(0.5 * x * step / np.pi)  # x sin(h)/h, h = x dtheta/2; 0 at x = 0
    return (1.0 + shift) * chord[:, None, None] - x_wind[:, None, None] * (
        np.asarray(mu, float)[:, None] * np.sin(theta)[None, :]
    )[None]


def geometry_ratio(
    phi_deg: float,
    delta_theta_deg: float,
    x: np.ndarray,
    mu: np.ndarray,
    theta: np.ndarray,
    offsets: tuple[np.ndarray, np.ndarray],
    x_wind: np.ndarray | None = None,
) -> np.ndarray:
    """Exact point pair over eq. 15 of the point at the same separation, ``(x, mu, theta)``.

    Both averaged over the range offset (:func:`offset_rule`): :func:`point_pair` at
    radius ``1 + v/R`` over :func:`_point_eq15` of its separation (chord less transport,
    :func:`_across`). What is left is the projection of the angle between the beams on
    the structure tensor, ``1 - O((x dtheta)^2)``, finite also where the wind cancels the
    scan (``a = b = 0``). Beam angle from ``x`` (steps), transport from ``x_wind`` (ray
    periods; ``x`` when ``None``, a swept pair): parallel beams (``x = 0``, a
    step-stare ray and itself later) have the ratio 1 exactly. Even in ``cos th`` (both
    depend on ``sin th`` and ``b^2`` only): ``theta`` of
    :func:`cwproc.physics.atable.full_circle` (a half circle and its mirror) is computed
    on its first half and repeated.
    """
    x_wind = x if x_wind is None else x_wind
    n_half = theta.size // 2
    if n_half and np.allclose(np.sin(theta[n_half:]), np.sin(theta[:n_half])):
        half = geometry_ratio(phi_deg, delta_theta_deg, x, mu, theta[:n_half], offsets, x_wind)
        return np.concatenate([half, half], axis=-1)
    exact = np.zeros((x.size, np.size(mu), theta.size))
    small = np.zeros_like(exact)
    for shift, w in zip(*offsets, strict=True):
        pair, eq15 = _offset_terms(phi_deg, delta_theta_deg, x, x_wind, mu, theta, float(shift))
        exact += w * pair
        small += w * eq15
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(small > 0, exact / np.where(small > 0, small, 1.0), 1.0)


#: the terms of the zero range offset of the last geometry (the same at every height)
_CENTRE_MEMO: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}


def _offset_terms(
    phi_deg: float,
    delta_theta_deg: float,
    x: np.ndarray,
    x_wind: np.ndarray,
    mu: np.ndarray,
    theta: np.ndarray,
    shift: float,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`point_pair` and :func:`_point_eq15` of one range offset, ``(x, mu, theta)``.

    Both per ``eps^(2/3)`` on the circle ``R' = 1`` (eq. 15 is homogeneous of degree 2/3
    in the separation). The zero offset does not depend on the height: its terms are
    kept for the next height of the same geometry (one geometry kept).
    """
    key = b""
    if shift == 0.0:
        parts = (np.array([phi_deg, delta_theta_deg]), x, x_wind, np.asarray(mu, float), theta)
        key = b"|".join(np.ascontiguousarray(p, dtype=float).tobytes() for p in parts)
        if key in _CENTRE_MEMO:
            return _CENTRE_MEMO[key]
    a, b = _components(mu, theta)
    step = math.radians(delta_theta_deg)
    pair = point_pair(phi_deg, delta_theta_deg, x, a, b, 1.0 + shift, x_wind)
    across = step * _across(x, mu, theta, shift, step, x_wind)
    eq15 = _point_eq15(across, (step * x_wind)[:, None, None] * b[None], phi_deg)
    if key:
        _CENTRE_MEMO.clear()
        _CENTRE_MEMO[key] = (pair, eq15)
    return pair, eq15


def swept_a2(
    plane: PlaneCurves,
    ratio: np.ndarray,
    kernel: tuple[np.ndarray, ...],
    *,
    phi_deg: float,
    delta_theta_deg: float,
    dy: float,
    offsets: tuple[np.ndarray, np.ndarray],
    same: float,
    mu: np.ndarray,
    theta: np.ndarray,
) -> np.ndarray:
    """A_2 integrand ``(lags, mu, theta)`` (m^(2/3)) of rays seen at their own times.

    The module's model: ``D0(x) = (E_v A(x_w dy b cos phi, dy sqrt(a_v^2 + (x_w b sin
    phi)^2)) + 2S) ratio - 2S`` with ``a_v`` of :func:`_across`, ``ratio`` of
    :func:`geometry_ratio` and ``2S = same``, then the kernel: :func:`sweep_kernel`
    (swept rays, ``x_w = x``), :func:`stare_kernel` or :func:`dwell_kernel` (step-stare
    rays, nodes ``(x, x_w)``; :func:`kernel_nodes`).
    ``theta``: azimuths of the wind from the scan's direction of motion (rad), a half
    circle ``th`` followed by its mirror ``pi - th`` (the probe part depends on ``sin th``
    and ``cos^2 th`` only); ``dy``: the azimuth step on the probe's circle (m).
    """
    x, x_wind, weights = kernel_nodes(kernel)
    n_half = theta.size // 2
    half = theta[:n_half]  # the integrand is even in cos(theta): the mirror half repeats it
    _, b = _components(mu, half)
    step = math.radians(delta_theta_deg)
    cphi, sphi = math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))
    moved = (x_wind * dy)[:, None, None] * np.abs(b)[None]  # transport along the beam
    along = moved * cphi
    probe_mean = np.zeros((x.size, *b.shape))
    for shift, w in zip(*offsets, strict=True):
        across = dy * np.hypot(_across(x, mu, half, shift, step, x_wind), moved * sphi / dy)
        probe_mean += w * plane(np.broadcast_to(along, across.shape), across)
    d0 = (probe_mean + same) * ratio[..., :n_half] - same
    out = np.einsum("lx,xmt->lmt", weights, d0)
    return np.concatenate([out, out], axis=-1)


def by_height(
    compute: Callable[[int], np.ndarray],
    ranges: np.ndarray,
    stride: int,
    direct: np.ndarray,
    advance: Callable[[int], Any] = lambda n: None,
) -> list[np.ndarray]:
    """``compute(j)`` at every ``stride``-th range, log-cubic in between.

    The pairs of a pulsed probe vary slowly with the range on the table's geometric
    nodes (through ``dy`` relative to the probe lengths and the offsets ``v / R``):
    ``log D`` is interpolated with 4-point Lagrange weights in ``log R`` from the nodes
    computed (the two nearest on each side, fewer at the ends). The ranges where
    ``direct`` holds (short ranges, where ``v / R`` is large) and the last two are
    always computed; where a value computed is not positive, every range is.
    ``advance(n)``: progress of ``n`` ranges. With the table's nodes (ratio 1.2) and
    stride 2 the interpolation error is below 1e-4 relative (30 m gate, 2 deg steps).
    """
    n = ranges.size
    nodes = set(range(0, n, max(1, stride))) | {n - 2, n - 1} | set(np.flatnonzero(direct))
    nodes = sorted(j for j in nodes if 0 <= j < n)
    done = {}
    for j in nodes:
        done[j] = compute(j)
        advance(1)
    if len(nodes) == n or any(np.any(done[j] <= 0) for j in nodes):
        out = [done[j] if j in done else compute(j) for j in range(n)]
        advance(n - len(nodes))
        return out
    x = np.log(ranges[nodes])
    logs = np.log(np.stack([done[j] for j in nodes]))
    out = []
    for j in range(n):
        if j in done:
            out.append(done[j])
            continue
        k = int(np.searchsorted(x, math.log(ranges[j])))
        window = np.arange(max(0, k - 2), min(len(nodes), k + 2))
        weights = _lagrange(x[window], math.log(ranges[j]))
        out.append(np.exp(np.tensordot(weights, logs[window], axes=1)))
        advance(1)
    return out


def _lagrange(nodes: np.ndarray, at: float) -> np.ndarray:
    """Lagrange interpolation weights of ``nodes`` at ``at``."""
    weights = np.ones(nodes.size)
    for i in range(nodes.size):
        for m in range(nodes.size):
            if m != i:
                weights[i] *= (at - nodes[m]) / (nodes[i] - nodes[m])
    return weights
