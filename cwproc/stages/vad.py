"""Stage ``vad``: the wind vector per scan and height from conical (VAD) scans.

For every 360 deg rotation (``scan >= 0``) and range gate, the least-squares fit of

.. math:: V_r(\\theta) = w \\sin\\phi + \\cos\\phi (u \\sin\\theta + v \\cos\\theta),

with ``theta`` the azimuth clockwise from north and ``phi`` the elevation of each ray
(Smalikho (2020), eq. 1 and eq. 8; Banakh et al. (1999), after eq. 23). All scans and
gates are solved at once: rays are laid out as ``(scan, ray in scan, gate)`` arrays
padded with masked entries, the 3x3 normal equations are summed with masked batched
matrix products, and solved in one batched call. Standard errors come from the
residual variance and ``(A^T A)^-1``; their behaviour with the number of rays, a
missing azimuth sector, shear and tilt is the error theory of seed 002
(:mod:`cwproc.physics.vad_errors`).

Homodyne cw lidars (ZephIR) measure only ``|V_r|``: the model becomes
``|A beta|``, fitted by Gauss-Newton. Because ``d|A beta|/d beta = sign(A beta) A``,
``J^T J = A^T A`` and a Gauss-Newton step is the linear fit of the *signed* data
``sign(A beta) |V_r|``: the fit alternates sign assignment and linear least squares,
starting from the best of a grid of sign patterns (wind direction every 5 deg plus the
all-positive pattern). ``beta`` and ``-beta`` fit equally well: the 180 deg ambiguity is
resolved by a reference direction (argument, a ``reference_direction`` variable of the
scan dataset, or the ``reference_direction_deg`` attribute, in this order).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import xarray as xr
from numpy.typing import NDArray

from cwproc.errors import CwprocError
from cwproc.physics.geometry import beam_unit_vector, height_from_range, normalise_pointing

#: elevations (deg) that count as conical scans; outside, w or u, v are not determined
CONICAL_ELEVATION_RANGE_DEG = (1.0, 89.0)
#: scans whose elevation differs from the selected one by more than this are left out
ELEVATION_TOLERANCE_DEG = 0.5
#: condition number of A^T A above which a fit is "bad" (ill-posed geometry)
MAX_CONDITION = 1e8
#: budget of (scan x ray x gate) elements per chunk; bounds memory on long days
CHUNK_ELEMENTS = 4_000_000
#: homodyne Gauss-Newton: most sign-assignment iterations
HOMODYNE_MAX_ITERATIONS = 50
#: homodyne start grid: wind directions (deg) of the candidate sign patterns
HOMODYNE_GRID_STEP_DEG = 5.0

REFERENCES = (
    "Smalikho (2020), eq. 1 and eq. 8; Banakh et al. (1999), after eq. 23; "
    "VAD accuracy paper (Theoretical accuracy of wind-vector reconstruction from lidar "
    "VAD scanning), sections 2-4"
)

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
ArrayLikeF = np.ndarray | float


# --------------------------------------------------------------------------------------
# layout: rays -> (scan, ray in scan)
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ScanLayout:
    """Rays of each scan as rows of a padded index table.

    Attributes
    ----------
    scan_ids : ndarray, shape (n_scan,)
        The scan numbers, increasing.
    index : ndarray, shape (n_scan, max_rays)
        Ray indices into the scan dataset; ``-1`` pads scans with fewer rays.
    """

    scan_ids: NDArray[np.int64]
    index: NDArray[np.int64]

    @property
    def present(self) -> BoolArray:
        """True where ``index`` names a ray (not padding)."""
        return self.index >= 0

    def take(self, values: np.ndarray, fill: float = np.nan) -> np.ndarray:
        """Gather ``values[ray, ...]`` into ``(scan, ray in scan, ...)``, padding with fill."""
        out = np.asarray(values)[np.maximum(self.index, 0)]
        if out.dtype.kind == "f":
            pad = ~self.present
            out[pad] = fill
        return out

    def subset(self, rows: slice) -> ScanLayout:
        """The layout of a contiguous block of scans."""
        return ScanLayout(self.scan_ids[rows], self.index[rows])


def scan_layout(scan: np.ndarray, keep: BoolArray | None = None) -> ScanLayout:
    """Group ray indices by scan number (rays with ``scan < 0`` or ``~keep`` left out).

    Parameters
    ----------
    scan : ndarray, shape (n_ray,)
        Scan index of each ray (``-1`` = no conical scan).
    keep : ndarray of bool, optional
        Rays to consider.

    Returns
    -------
    ScanLayout
    """
    scan = np.asarray(scan).astype(np.int64)
    use = scan >= 0
    if keep is not None:
        use &= keep
    rays = np.flatnonzero(use)
    order = rays[np.argsort(scan[rays], kind="stable")]
    ids, starts, counts = np.unique(scan[order], return_index=True, return_counts=True)
    index = np.full((ids.size, int(counts.max()) if ids.size else 0), -1, dtype=np.int64)
    if ids.size:
        position = np.arange(order.size) - np.repeat(starts, counts)
        index[np.repeat(np.arange(ids.size), counts), position] = order
    return ScanLayout(ids.astype(np.int64), index)


def scan_chunks(layout: ScanLayout, n_gates: int) -> Iterator[slice]:
    """Contiguous blocks of scans whose padded arrays hold at most ``CHUNK_ELEMENTS``."""
    n_scan, max_rays = layout.index.shape
    per_scan = max(1, max_rays * max(n_gates, 1))
    step = max(1, CHUNK_ELEMENTS // per_scan)
    for start in range(0, n_scan, step):
        yield slice(start, min(start + step, n_scan))


# --------------------------------------------------------------------------------------
# batched least squares
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BatchedFit:
    """Result of a batched VAD fit over ``(scan, gate)``.

    Attributes
    ----------
    beta : ndarray, shape (S, G, 3)
        Fitted (u, v, w) (m s-1); NaN where the fit is not determined.
    covariance : ndarray, shape (S, G, 3, 3)
        ``s^2 (A^T A)^-1`` (m2 s-2); NaN without residual degrees of freedom.
    n_rays : ndarray, shape (S, G)
        Rays used.
    residual_std : ndarray, shape (S, G)
        ``sqrt(SSR / (n - 3))`` (m s-1).
    determined : ndarray of bool, shape (S, G)
        At least 3 rays and ``cond(A^T A) <= MAX_CONDITION``.
    converged : ndarray of bool, shape (S, G)
        Homodyne iterations reached a fixed point (always true for linear fits).
    residuals : ndarray, shape (S, R, G)
        Data minus model for every ray (also the unused ones; NaN for padding) (m s-1).
    """

    beta: FloatArray
    covariance: FloatArray
    n_rays: NDArray[np.int64]
    residual_std: FloatArray
    determined: BoolArray
    converged: BoolArray
    residuals: FloatArray


def _normal_matrix(design: FloatArray, weight: FloatArray) -> FloatArray:
    """``sum_r w_srg a_srj a_srk`` as (S, G, 3, 3) by one batched matrix product."""
    s, r, _ = design.shape
    outer = (design[:, :, :, None] * design[:, :, None, :]).reshape(s, r, 9)
    return np.matmul(weight.transpose(0, 2, 1), outer).reshape(s, weight.shape[2], 3, 3)


def inverse_3x3(m: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Batched inverse of 3x3 matrices by the adjugate, and the determinants.

    Much faster than ``np.linalg.inv`` for ~1e5 small matrices (no per-matrix LAPACK
    call). Singular matrices give non-finite entries.
    """
    a, b, c = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    d, e, f = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    g, h, i = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    cof = np.stack(
        [
            e * i - f * h, c * h - b * i, b * f - c * e,
            f * g - d * i, a * i - c * g, c * d - a * f,
            d * h - e * g, b * g - a * h, a * e - b * d,
        ],
        axis=-1,
    ).reshape(m.shape)  # fmt: skip
    det = a * cof[..., 0, 0] + b * cof[..., 1, 0] + c * cof[..., 2, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        return cof / det[..., None, None], det


def _safe_inverse(ata: FloatArray, n_rays: np.ndarray) -> tuple[FloatArray, BoolArray]:
    """Batched inverse of the normal matrices; undetermined ones come back as NaN.

    Undetermined: fewer than 3 rays, or the Frobenius condition number
    ``||M||_F ||M^-1||_F`` (an upper bound of the 2-norm one, at most 3 times larger)
    above ``MAX_CONDITION``.
    """
    finite = np.all(np.isfinite(ata), axis=(-2, -1))
    ok = (n_rays >= 3) & finite
    safe = np.where(ok[..., None, None], ata, np.eye(3))
    inverse, _ = inverse_3x3(safe)
    with np.errstate(invalid="ignore", over="ignore"):
        cond = np.sqrt(np.sum(safe**2, axis=(-2, -1)) * np.sum(inverse**2, axis=(-2, -1)))
    ok &= np.isfinite(cond) & (cond <= MAX_CONDITION)
    inverse = np.where(ok[..., None, None], inverse, np.nan)
    return inverse, ok


def _solve(inverse: FloatArray, design: FloatArray, weighted_y: FloatArray) -> FloatArray:
    """``(A^T A)^-1 A^T y`` for all (scan, gate): (S, G, 3)."""
    aty = np.matmul(weighted_y.transpose(0, 2, 1), design)
    return np.einsum("sgjk,sgk->sgj", inverse, aty)


def _model(design: FloatArray, beta: FloatArray) -> FloatArray:
    """``A beta`` for every ray: (S, R, G)."""
    return np.matmul(design, np.nan_to_num(beta).transpose(0, 2, 1))


def _finish(
    beta: FloatArray,
    inverse: FloatArray,
    determined: BoolArray,
    converged: BoolArray,
    residuals: FloatArray,
    valid: BoolArray,
) -> BatchedFit:
    n_rays = valid.sum(axis=1)
    ssr = np.sum(np.where(valid, residuals, 0.0) ** 2, axis=1)
    dof = n_rays - 3
    with np.errstate(invalid="ignore", divide="ignore"):
        variance = np.where(determined & (dof > 0), ssr / np.maximum(dof, 1), np.nan)
    beta = np.where(determined[..., None], beta, np.nan)
    return BatchedFit(
        beta=beta,
        covariance=variance[..., None, None] * inverse,
        n_rays=n_rays.astype(np.int64),
        residual_std=np.sqrt(variance),
        determined=determined,
        converged=converged,
        residuals=residuals,
    )


def fit_linear(velocity: FloatArray, design: FloatArray, valid: BoolArray) -> BatchedFit:
    """Least-squares VAD fit of every (scan, gate) at once (Smalikho (2020), eq. 1).

    Parameters
    ----------
    velocity : ndarray, shape (S, R, G)
        Radial velocity (m s-1), positive away from the lidar.
    design : ndarray, shape (S, R, 3)
        :func:`cwproc.physics.geometry.beam_unit_vector` of each ray (padding: any finite value).
    valid : ndarray of bool, shape (S, R, G)
        Which entries enter the fit.

    Returns
    -------
    BatchedFit
    """
    design = np.nan_to_num(design)
    weight = valid.astype(float)
    y = np.where(valid, velocity, 0.0)
    inverse, determined = _safe_inverse(_normal_matrix(design, weight), weight.sum(axis=1))
    beta = _solve(np.nan_to_num(inverse), design, y)
    residuals = velocity - _model(design, beta)
    return _finish(beta, inverse, determined, np.ones_like(determined), residuals, valid)


def _sign_iterations(
    y: FloatArray, design: FloatArray, weight: FloatArray, inv0: FloatArray, beta: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """Gauss-Newton on ``|A beta|`` from ``beta``: refit ``sign(A beta) |V_r|`` to a fixed point."""
    signs = np.where(_model(design, beta) >= 0, 1.0, -1.0)
    converged = np.zeros(beta.shape[:2], dtype=bool)
    for _ in range(HOMODYNE_MAX_ITERATIONS):
        beta = _solve(inv0, design, y * signs)
        new_signs = np.where(_model(design, beta) >= 0, 1.0, -1.0)
        converged = np.all((new_signs == signs) | (weight == 0), axis=1)
        signs = new_signs
        if converged.all():
            break
    return beta, converged


def _best_of_patterns(
    y: FloatArray,
    design: FloatArray,
    weight: FloatArray,
    inv0: FloatArray,
    patterns: list[FloatArray],
    best_beta: FloatArray,
) -> FloatArray:
    """The linear fit of ``pattern * |V_r|`` of least ``|V_r| - |A beta|`` cost per cell."""

    def cost(beta: FloatArray) -> FloatArray:
        return np.sum(weight * (y - np.abs(_model(design, beta))) ** 2, axis=1)

    best_cost = cost(best_beta)
    for signs in patterns:
        beta = _solve(inv0, design, y * signs)
        c = cost(beta)
        better = c < best_cost
        best_cost = np.where(better, c, best_cost)
        best_beta = np.where(better[..., None], beta, best_beta)
    return best_beta


def homodyne_start_patterns(theta: FloatArray) -> list[FloatArray]:
    """Sign patterns ``sign(cos(theta - t))``, t every ``HOMODYNE_GRID_STEP_DEG`` in [0, 180).

    The patterns of a purely horizontal wind; ``theta`` (S, R) azimuths (rad). Each
    pattern is (S, R, 1).
    """
    return [
        np.where(np.cos(theta - t) >= 0, 1.0, -1.0)[:, :, None]
        for t in np.deg2rad(np.arange(0.0, 180.0, HOMODYNE_GRID_STEP_DEG))
    ]


def homodyne_arc_patterns(theta: FloatArray, beta: FloatArray) -> list[FloatArray]:
    """Sign patterns of ``a + b cos(theta - t)`` about the fitted direction ``t``.

    With a vertical wind (``a = w sin(phi) != 0``) the radial velocity changes sign at
    two azimuths that are not 180 deg apart: the negative rays form an arc of any width
    centred on the downwind side. Taking the direction ``t`` of a first fit (which the
    half-circle patterns find well) and every arc half width ``h`` in 10 deg steps gives
    the pattern of the global minimum, which Gauss-Newton from a half-circle start can
    miss (8 rays, phi = 52 deg, u = 0, v = 2, w = 0.75 converged to v = 1.16, w = 1.13).
    ``theta`` (S, R) (rad), ``beta`` (S, G, 3); patterns (S, R, G).
    """
    direction = np.arctan2(beta[..., 0], beta[..., 1])[:, None, :]  # (S, 1, G)
    cos_dev = np.cos(theta[:, :, None] - direction)
    out = [np.ones_like(cos_dev)]
    for half_width in np.deg2rad(np.arange(5.0, 180.0, 10.0)):
        out.append(np.where(cos_dev >= np.cos(half_width), 1.0, -1.0))
    return out


def fit_homodyne(
    magnitude: FloatArray,
    design: FloatArray,
    valid: BoolArray,
    start: FloatArray | None = None,
) -> BatchedFit:
    """Fit ``|V_r| = |A beta|`` (homodyne cw lidar, Wagner et al. (DTU)) for every (scan, gate).

    Gauss-Newton on ``|A beta|``: each step is the linear fit of ``sign(A beta) |V_r|``
    (``J^T J = A^T A``), iterated until no sign changes, started from the best of the
    sign patterns of a horizontal wind (:func:`homodyne_start_patterns`) and the
    all-positive pattern. The result is then refined from the arc patterns about its
    direction (:func:`homodyne_arc_patterns`), which hold the global minimum when a
    vertical wind moves the sign changes off the half circle; the lower cost wins.
    ``beta`` is returned with an arbitrary overall sign (see
    :func:`resolve_homodyne_ambiguity`).

    Parameters
    ----------
    magnitude : ndarray, shape (S, R, G)
        Measured ``|V_r|`` (m s-1); the sign of the input is ignored.
    design : ndarray, shape (S, R, 3)
        :func:`cwproc.physics.geometry.beam_unit_vector` of each ray.
    valid : ndarray of bool, shape (S, R, G)
    start : ndarray, shape (S, G, 3), optional
        A starting ``beta`` (e.g. from a previous fit of the same data); replaces the
        grid of sign patterns where it is finite.

    Returns
    -------
    BatchedFit
        Residuals are ``|V_r| - |A beta|``.
    """
    design = np.nan_to_num(design)
    weight = valid.astype(float)
    y = np.where(valid, np.abs(magnitude), 0.0)
    inverse, determined = _safe_inverse(_normal_matrix(design, weight), weight.sum(axis=1))
    inv0 = np.nan_to_num(inverse)
    # azimuth of each ray from the design row: theta = atan2(sin, cos)
    theta = np.arctan2(design[..., 0], design[..., 1])
    first = _solve(inv0, design, y)
    warm = None if start is None else np.all(np.isfinite(start), axis=-1)
    if warm is None or not warm.all():
        first = _best_of_patterns(y, design, weight, inv0, homodyne_start_patterns(theta), first)
    if start is not None and warm is not None:
        first = np.where(warm[..., None], start, first)
    beta, converged = _sign_iterations(y, design, weight, inv0, first)
    refined_start = _best_of_patterns(
        y, design, weight, inv0, homodyne_arc_patterns(theta, beta), beta
    )
    refined, refined_converged = _sign_iterations(y, design, weight, inv0, refined_start)

    def cost(b: FloatArray) -> FloatArray:
        return np.sum(weight * (y - np.abs(_model(design, b))) ** 2, axis=1)

    better = cost(refined) < cost(beta)
    beta = np.where(better[..., None], refined, beta)
    converged = np.where(better, refined_converged, converged)
    residuals = np.abs(magnitude) - np.abs(_model(design, beta))
    return _finish(beta, inverse, determined, converged, residuals, valid)


def fit_least_absolute(
    values: FloatArray,
    design: FloatArray,
    valid: BoolArray,
    *,
    homodyne: bool,
    iterations: int = 20,
    floor: float = 0.01,
    tolerance: float = 0.005,
) -> tuple[FloatArray, FloatArray]:
    """Residuals about a least-absolute-deviations (L1) VAD fit of every (scan, gate).

    A robust first fit for outlier screening: with a balanced azimuth design the L1 fit
    is not pulled by a minority of wild radial velocities, unlike least squares. Solved by
    iteratively reweighted least squares, weights ``1 / max(|r|, floor)``, started from
    :func:`fit_scans`; for homodyne data each step re-assigns the signs as in
    :func:`fit_homodyne`.

    Parameters
    ----------
    values : ndarray, shape (S, R, G)
        Radial velocities (homodyne: magnitudes) (m s-1).
    design : ndarray, shape (S, R, 3)
        :func:`cwproc.physics.geometry.beam_unit_vector` of each ray.
    valid : ndarray of bool, shape (S, R, G)
    homodyne : bool
        Fit ``|A beta|`` instead of ``A beta``.
    iterations : int, optional
        Most IRLS iterations.
    floor : float, optional
        Smallest residual (m s-1) in the weights.
    tolerance : float, optional
        Stop when no coefficient changes by more than this (m s-1); screening needs
        residuals only to a fraction of the noise.

    Returns
    -------
    (beta, residuals) : ndarray (S, G, 3), ndarray (S, R, G)
        The L1 coefficients (m s-1; NaN where not determined) and data minus model
        (homodyne: ``|V_r| - |A beta|``) (m s-1).
    """
    start = fit_scans(values, design, valid, homodyne=homodyne)
    design = np.nan_to_num(design)
    ok = start.determined
    beta = np.nan_to_num(start.beta)
    y = np.where(valid, np.abs(values) if homodyne else values, 0.0)
    for _ in range(iterations):
        model = _model(design, beta)
        target = y * np.where(model >= 0, 1.0, -1.0) if homodyne else y
        weight = valid / np.maximum(np.abs(target - model), floor)
        ata = np.where(ok[..., None, None], _normal_matrix(design, weight), np.eye(3))
        new = np.where(ok[..., None], _solve(inverse_3x3(ata)[0], design, weight * target), beta)
        change = float(np.max(np.abs(new - beta), initial=0.0))
        beta = new
        if change < tolerance:
            break
    model = _model(design, beta)
    residuals = np.abs(values) - np.abs(model) if homodyne else values - model
    return np.where(ok[..., None], beta, np.nan), residuals


def fit_scans(
    velocity: FloatArray,
    design: FloatArray,
    valid: BoolArray,
    *,
    homodyne: bool,
    start: FloatArray | None = None,
) -> BatchedFit:
    """:func:`fit_homodyne` (warm-started from ``start``) when ``homodyne``, else
    :func:`fit_linear` (which needs no start)."""
    if homodyne:
        return fit_homodyne(velocity, design, valid, start)
    return fit_linear(velocity, design, valid)


# --------------------------------------------------------------------------------------
# derived quantities
# --------------------------------------------------------------------------------------


def wind_from_direction(u: ArrayLikeF, v: ArrayLikeF) -> FloatArray:
    """Direction the wind blows from (deg clockwise from north), ``atan2(-u, -v)``."""
    return np.rad2deg(np.arctan2(-np.asarray(u), -np.asarray(v))) % 360.0


def speed_direction_errors(
    u: FloatArray, v: FloatArray, covariance: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Standard errors of speed and direction by first-order propagation.

    ``var(S) = (u^2 C_uu + v^2 C_vv + 2 u v C_uv) / S^2`` and
    ``var(D) = (v^2 C_uu + u^2 C_vv - 2 u v C_uv) / S^4`` (rad^2), S = hypot(u, v).

    Parameters
    ----------
    u, v : ndarray
        Wind components (m s-1).
    covariance : ndarray, shape (..., 3, 3)
        Covariance of (u, v, w) (m2 s-2).

    Returns
    -------
    (speed_error, direction_error) : (m s-1, deg)
    """
    cuu, cvv, cuv = covariance[..., 0, 0], covariance[..., 1, 1], covariance[..., 0, 1]
    s2 = u**2 + v**2
    with np.errstate(invalid="ignore", divide="ignore"):
        var_s = (u**2 * cuu + v**2 * cvv + 2 * u * v * cuv) / s2
        var_d = (v**2 * cuu + u**2 * cvv - 2 * u * v * cuv) / s2**2
    return np.sqrt(np.maximum(var_s, 0.0)), np.rad2deg(np.sqrt(np.maximum(var_d, 0.0)))


def azimuth_gap(azimuth_deg: FloatArray, valid: BoolArray) -> FloatArray:
    """Largest azimuth gap (deg) between the valid rays of each (scan, gate), wrapping 360.

    Parameters
    ----------
    azimuth_deg : ndarray, shape (S, R)
        Azimuths in [0, 360) (deg).
    valid : ndarray of bool, shape (S, R, G)

    Returns
    -------
    ndarray, shape (S, G)
        360 where fewer than two rays are valid.
    """
    az = np.where(valid, azimuth_deg[:, :, None], np.nan)
    az = np.sort(az, axis=1)  # NaN last
    n = valid.sum(axis=1)
    inner = np.diff(az, axis=1)
    inner = np.where(np.isnan(inner), -np.inf, inner).max(axis=1, initial=-np.inf)
    first = az[:, 0, :]
    last = np.take_along_axis(az, np.maximum(n - 1, 0)[:, None, :], axis=1)[:, 0, :]
    gap = np.maximum(inner, first + 360.0 - last)
    return np.where(n >= 2, gap, 360.0)


def _circular_difference(a: FloatArray, b: FloatArray) -> FloatArray:
    """Smallest absolute angle between directions a and b (deg)."""
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


def resolve_homodyne_ambiguity(beta: FloatArray, reference_deg: FloatArray) -> FloatArray:
    """Choose between ``beta`` and ``-beta``: the from-direction nearest the reference.

    Parameters
    ----------
    beta : ndarray, shape (S, G, 3)
        Fitted (u, v, w) with arbitrary overall sign.
    reference_deg : ndarray, shape (S,) or scalar
        Reference wind-from direction (deg from north).

    Returns
    -------
    ndarray, shape (S, G, 3)
    """
    direction = wind_from_direction(beta[..., 0], beta[..., 1])
    reference = np.broadcast_to(np.asarray(reference_deg, dtype=float), beta.shape[:1])
    flip = _circular_difference(direction, reference[:, None]) > 90.0
    return np.where(flip[..., None], -beta, beta)


# --------------------------------------------------------------------------------------
# the stage
# --------------------------------------------------------------------------------------


def is_homodyne(ds: xr.Dataset) -> bool:
    """Whether the scan dataset holds homodyne (``|V_r|`` only) data."""
    value = ds.attrs.get("homodyne", 0)
    if isinstance(value, str):
        return value.strip().lower() in ("1", "true", "yes")
    return bool(np.asarray(value).item())


def pointing(ds: xr.Dataset) -> tuple[FloatArray, FloatArray]:
    """Azimuth in [0, 360) and elevation in [-90, 90] of every ray (deg)."""
    return normalise_pointing(ds["azimuth"].values, ds["elevation"].values)


def usable_mask(ds: xr.Dataset) -> BoolArray:
    """(ray, range) entries a fit may use: finite and, when screened, flag 0."""
    valid = np.isfinite(ds["radial_velocity"].values)
    if "qc_flag_radial" in ds:
        valid &= ds["qc_flag_radial"].values == 0
    return valid


def _require(ds: xr.Dataset, names: tuple[str, ...]) -> None:
    missing = [n for n in names if n not in ds.variables]
    if missing:
        raise CwprocError(
            "The VAD fit needs a scan dataset with "
            + ", ".join(names)
            + f"; this one lacks {', '.join(missing)}."
        )


def select_conical_scans(
    layout: ScanLayout, elevation_deg: FloatArray
) -> tuple[ScanLayout, float, FloatArray, int]:
    """Keep the scans at the most common conical elevation.

    A scan is conical when its median elevation lies in ``CONICAL_ELEVATION_RANGE_DEG``.
    The most common elevation (rounded to 0.1 deg) is chosen; scans within
    ``ELEVATION_TOLERANCE_DEG`` of it are kept.

    Returns
    -------
    (layout, elevation_deg, scan_elevations_deg, n_other_elevation)

    Raises
    ------
    CwprocError
        No conical scan at all (e.g. a vertical stare file).
    """
    per_scan = np.nanmedian(layout.take(elevation_deg), axis=1) if layout.index.size else []
    per_scan = np.asarray(per_scan, dtype=float)
    lo, hi = CONICAL_ELEVATION_RANGE_DEG
    conical = (per_scan >= lo) & (per_scan <= hi)
    if not conical.any():
        raise CwprocError(
            "The input has no conical scan (no 360-degree rotation at an elevation between "
            f"{lo:g} and {hi:g} degrees), so no wind profile can be fitted; a vertical stare "
            "or an RHI file cannot give a VAD wind."
        )
    values, counts = np.unique(np.round(per_scan[conical], 1), return_counts=True)
    chosen = float(values[np.argmax(counts)])
    keep = conical & (np.abs(per_scan - chosen) <= ELEVATION_TOLERANCE_DEG)
    n_other = int(conical.sum() - keep.sum())
    rows = np.flatnonzero(keep)
    return (
        ScanLayout(layout.scan_ids[rows], layout.index[rows]),
        chosen,
        per_scan[rows],
        n_other,
    )


def _reference_directions(
    ds: xr.Dataset, layout: ScanLayout, reference_direction_deg: float | None
) -> tuple[FloatArray, str]:
    """Per-scan reference wind-from direction for homodyne data, and how it was obtained."""
    n_scan = layout.scan_ids.size
    if reference_direction_deg is not None:
        return (
            np.full(n_scan, float(reference_direction_deg)),
            f"configured reference direction {float(reference_direction_deg):g} deg",
        )
    if "reference_direction" in ds and ds["reference_direction"].dims == ("ray",):
        rad = np.deg2rad(layout.take(ds["reference_direction"].values.astype(float)))
        mean = np.rad2deg(np.arctan2(np.nanmean(np.sin(rad), 1), np.nanmean(np.cos(rad), 1)))
        if np.all(np.isfinite(mean)):
            return mean % 360.0, "measured reference direction (variable reference_direction)"
    attr = ds.attrs.get("reference_direction_deg")
    if attr is not None and np.isfinite(float(attr)):
        return (
            np.full(n_scan, float(attr)),
            f"reference direction {float(attr):g} deg from the input attribute "
            "reference_direction_deg",
        )
    raise CwprocError(
        "Homodyne lidar data measure only |V_r|, so the wind direction is ambiguous by 180 "
        "degrees; set vad.reference_direction_deg in the configuration or provide a "
        "measured reference_direction (deg) in the input."
    )


def _mean_times(ds: xr.Dataset, layout: ScanLayout) -> np.ndarray:
    """Mean ray time of each scan, averaged from the scan's own earliest ray.

    Offsets from the scan's own origin keep the float sums small (exact to the
    nanosecond) and make the result independent of what else the dataset holds.
    """
    times = layout.take(ds["time"].values.astype("datetime64[ns]").astype(np.int64))
    good = layout.present & (times != np.iinfo(np.int64).min)
    t0 = np.where(good, times, np.iinfo(np.int64).max).min(axis=1)
    t0 = np.where(good.any(axis=1), t0, 0)
    offsets = np.where(good, times - t0[:, None], 0).astype(float)
    offsets[~good] = np.nan
    mean = np.nanmean(offsets, axis=1)
    return (t0 + np.round(mean).astype(np.int64)).astype("datetime64[ns]")


def fit_vad(
    ds: xr.Dataset,
    *,
    min_rays: int,
    max_gap_deg: float,
    reference_direction_deg: float | None = None,
    max_residual_std: float = 3.0,
) -> xr.Dataset:
    """Wind vector per conical scan and height (Smalikho (2020), eq. 1).

    Parameters
    ----------
    ds : xarray.Dataset
        Scan dataset (``docs/DEVELOPING.md``), optionally screened by
        :func:`cwproc.stages.qc.screen_radial_velocity`; only entries with
        ``qc_flag_radial == 0`` (or, unscreened, finite ones) are used.
    min_rays : int
        Fewest rays for a good fit (fewer: flag bit 1; fewer than 3: no fit).
    max_gap_deg : float
        Largest azimuth gap between used rays (deg) before flag bit 2.
    reference_direction_deg : float, optional
        Homodyne data only: wind-from direction (deg from north) that resolves the
        180 deg ambiguity. When None, a ``reference_direction(ray)`` variable or the
        ``reference_direction_deg`` attribute of ``ds`` is used.
    max_residual_std : float, optional
        Residual standard deviation (m s-1) above which a fit is flagged bad (bit 4):
        3 m s-1 is far above the noise of good gates (< 0.5 m s-1) plus the turbulent
        scatter of a scan (~1 m s-1), and typical of noise gates or folded velocities.

    Returns
    -------
    xarray.Dataset
        The wind product: dims ``(time, height)``; ``qc_flag`` bits: 1 fewer than
        ``min_rays`` rays, 2 azimuth gap > ``max_gap_deg``, 4 bad fit (not determined:
        < 3 rays or ``cond(A^T A) > 1e8``; no residual degree of freedom, so no
        error estimate; residual std > ``max_residual_std``; homodyne iterations not
        converged).

    Raises
    ------
    CwprocError
        Missing variables, no conical scan, or homodyne data without any reference
        direction.
    """
    _require(ds, ("radial_velocity", "azimuth", "elevation", "scan", "time", "range"))
    if ds["radial_velocity"].dims != ("ray", "range"):
        raise CwprocError(
            "The VAD fit needs radial_velocity with dimensions (ray, range); this input has "
            f"{ds['radial_velocity'].dims}."
        )
    azimuth, elevation = pointing(ds)
    layout, phi, scan_elevation, n_other = select_conical_scans(
        scan_layout(ds["scan"].values, np.isfinite(azimuth) & np.isfinite(elevation)),
        elevation,
    )
    homodyne = is_homodyne(ds)
    velocity = ds["radial_velocity"].values.astype(float)
    valid_all = usable_mask(ds)
    n_gates = velocity.shape[1]
    parts: list[dict[str, np.ndarray]] = []
    for rows in scan_chunks(layout, n_gates):
        sub = layout.subset(rows)
        present = sub.present[:, :, None]
        valid = sub.take(valid_all) & present
        design = beam_unit_vector(sub.take(azimuth), sub.take(elevation))
        fit = fit_scans(sub.take(velocity), design, valid, homodyne=homodyne)
        parts.append(
            {
                "beta": fit.beta,
                "cov": fit.covariance,
                "n": fit.n_rays,
                "res": fit.residual_std,
                "ok": fit.determined & fit.converged,
                "gap": azimuth_gap(sub.take(azimuth), valid),
            }
        )
    joined = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    beta = joined["beta"]
    attrs_resolution = "not applicable (heterodyne: signed radial velocities)"
    if homodyne:
        reference, attrs_resolution = _reference_directions(ds, layout, reference_direction_deg)
        beta = resolve_homodyne_ambiguity(beta, reference)
    return _wind_dataset(
        ds,
        layout,
        beta=beta,
        covariance=joined["cov"],
        n_rays=joined["n"],
        residual_std=joined["res"],
        fit_ok=joined["ok"],
        gap=joined["gap"],
        phi=phi,
        scan_elevation=scan_elevation,
        n_other=n_other,
        homodyne=homodyne,
        resolution=attrs_resolution,
        params={
            "min_rays": min_rays,
            "max_gap_deg": max_gap_deg,
            "max_residual_std": max_residual_std,
        },
    )


def _wind_dataset(
    ds: xr.Dataset,
    layout: ScanLayout,
    *,
    beta: FloatArray,
    covariance: FloatArray,
    n_rays: np.ndarray,
    residual_std: FloatArray,
    fit_ok: BoolArray,
    gap: FloatArray,
    phi: float,
    scan_elevation: FloatArray,
    n_other: int,
    homodyne: bool,
    resolution: str,
    params: dict[str, float],
) -> xr.Dataset:
    u, v, w = beta[..., 0], beta[..., 1], beta[..., 2]
    speed_error, direction_error = speed_direction_errors(u, v, covariance)
    bad = ~fit_ok | ~np.isfinite(residual_std) | (residual_std > params["max_residual_std"])
    flag = (
        np.where(n_rays < params["min_rays"], 1, 0)
        | np.where(gap > params["max_gap_deg"], 2, 0)
        | np.where(bad, 4, 0)
    ).astype(np.int8)
    dims = ("time", "height")
    method = (
        "homodyne least squares |V_r| = |w sin(phi) + cos(phi)(u sin(theta) + v cos(theta))| "
        "(Gauss-Newton by sign assignment)"
        if homodyne
        else "least squares V_r = w sin(phi) + cos(phi)(u sin(theta) + v cos(theta))"
    )
    fit_attrs = {"method": method, "references": REFERENCES}
    error_attrs = {
        "method": "square root of the diagonal of s^2 (A^T A)^-1, s^2 = SSR/(n - 3)",
        "references": "VAD accuracy paper, section 4",
    }
    range_m = ds["range"].values.astype(float)
    height = height_from_range(range_m, phi)
    out = xr.Dataset(
        {
            "u": (dims, u, fit_attrs),
            "v": (dims, v, fit_attrs),
            "w": (dims, w, fit_attrs),
            "wind_speed": (dims, np.hypot(u, v), fit_attrs),
            "wind_direction": (dims, wind_from_direction(u, v), fit_attrs),
            "u_error": (dims, np.sqrt(covariance[..., 0, 0]), error_attrs),
            "v_error": (dims, np.sqrt(covariance[..., 1, 1]), error_attrs),
            "w_error": (dims, np.sqrt(covariance[..., 2, 2]), error_attrs),
            "wind_speed_error": (dims, speed_error, {"method": "first-order propagation"}),
            "wind_direction_error": (
                dims,
                direction_error,
                {"method": "first-order propagation"},
            ),
            "residual_std": (dims, residual_std),
            "n_rays": (dims, n_rays.astype(np.int32)),
            "max_azimuth_gap": (dims, gap),
            "qc_flag": (
                dims,
                flag,
                {
                    "flag_masks": np.array([1, 2, 4], dtype=np.int8),
                    "flag_meanings": "too_few_rays azimuth_gap_too_large bad_fit",
                    "bad_fit_definition": (
                        "fewer than 3 rays or cond(A^T A) > 1e8; no residual degree of "
                        "freedom (n = 3); residual std > "
                        f"{params['max_residual_std']:g} m s-1; homodyne fit not converged"
                    ),
                },
            ),
        },
        coords={
            "time": ("time", _mean_times(ds, layout)),
            "height": ("height", height),
            "range": ("height", range_m),
            "scan": ("time", layout.scan_ids),
            "elevation": ("time", scan_elevation),
        },
    )
    out.attrs = {k: v for k, v in ds.attrs.items()}
    out.attrs.update(
        {
            "vad_method": method,
            "vad_references": REFERENCES,
            "vad_min_rays": int(params["min_rays"]),
            "vad_max_gap_deg": float(params["max_gap_deg"]),
            "vad_max_residual_std_m_s": float(params["max_residual_std"]),
            "vad_elevation_deg": phi,
            "vad_elevation_selection": (
                f"scans at the most common conical elevation {phi:g} deg "
                f"(+-{ELEVATION_TOLERANCE_DEG:g} deg) are fitted; {n_other} conical scan(s) "
                "at other elevations were left out"
            ),
            "vad_scans_other_elevation": n_other,
            "vad_homodyne_ambiguity": resolution,
        }
    )
    return out
