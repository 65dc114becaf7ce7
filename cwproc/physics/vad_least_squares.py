"""Batched least-squares VAD fits of every (scan, gate) at once (numpy only).

The fits of the stages ``qc`` (:mod:`cwproc.stages.qc`) and ``vad``
(:mod:`cwproc.stages.vad`); moved here from ``cwproc.stages.vad_fit`` (issue 33).

The model of each ray is ``V_r = A beta``, ``A`` the beam unit vector
(:func:`cwproc.physics.geometry.beam_unit_vector`) and ``beta = (u, v, w)``
(Smalikho (2020), eq. 1 and eq. 8). Rays are laid out as ``(scan, ray in scan, gate)``
arrays padded with masked entries; the 3x3 normal equations are summed with masked
batched matrix products and solved by batched adjugate inverses (the iterations of the
L1 fit of the outlier screening sum only the 6 distinct entries of the symmetric matrix
and solve by the cofactors, Cramer's rule). Standard errors come from the residual
variance and ``(A^T A)^-1``.

Homodyne cw lidars (ZephIR) measure only ``|V_r|``: the model becomes ``|A beta|``,
fitted by Gauss-Newton. Because ``d|A beta|/d beta = sign(A beta) A``,
``J^T J = A^T A`` and a Gauss-Newton step is the linear fit of the *signed* data
``sign(A beta) |V_r|``: the fit alternates sign assignment and linear least squares,
started at the global minimum over all arc sign patterns
(:func:`homodyne_global_start`). ``beta`` and ``-beta`` fit equally well;
:func:`cwproc.stages.vad.resolve_homodyne_ambiguity` chooses between them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: condition number of A^T A above which a fit is "bad" (ill-posed geometry)
MAX_CONDITION = 1e8
#: homodyne Gauss-Newton: most sign-assignment iterations
HOMODYNE_MAX_ITERATIONS = 50
#: homodyne arc search: most (scan x ray x gate) elements per block (memory bound)
HOMODYNE_BLOCK_ELEMENTS = 500_000
#: L1 fit: the still-moving cells are packed anew when that leaves at most this share of
#: the batch's columns (packing copies the batch's arrays)
PACK_FRACTION = 0.5

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

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


def _design_outer(design: FloatArray) -> FloatArray:
    """``a_srj a_srk`` of every ray as (S, R, 9)."""
    s, r, _ = design.shape
    return (design[:, :, :, None] * design[:, :, None, :]).reshape(s, r, 9)


def _normal_matrix(
    design: FloatArray, weight: FloatArray, outer: FloatArray | None = None
) -> FloatArray:
    """``sum_r w_srg a_srj a_srk`` as (S, G, 3, 3) by one batched matrix product.

    ``outer`` is :func:`_design_outer` of ``design`` when the caller holds it.
    """
    s = design.shape[0]
    outer = _design_outer(design) if outer is None else outer
    return np.matmul(weight.transpose(0, 2, 1), outer).reshape(s, weight.shape[2], 3, 3)


#: (j, k) of the distinct entries ``a b c e f i`` of a symmetric 3x3 matrix
#: ``[[a, b, c], [b, e, f], [c, f, i]]``
_SYM_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _design_pairs(design: FloatArray) -> FloatArray:
    """``a_srj a_srk`` of every ray for the 6 distinct (j, k) of :data:`_SYM_PAIRS`: (S, R, 6)."""
    return np.stack([design[..., j] * design[..., k] for j, k in _SYM_PAIRS], axis=-1)


def _normal_equations(
    design: FloatArray, weight: FloatArray, weighted_y: FloatArray, pairs: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The distinct entries of ``sum_r w a_j a_k`` (S, G, 6) and ``sum_r w y a_j`` (S, G, 3).

    Two batched matrix products over the rays (``pairs``: :func:`_design_pairs`).
    """
    m = np.matmul(weight.transpose(0, 2, 1), pairs)
    return m, np.matmul(weighted_y.transpose(0, 2, 1), design)


def _cofactors(m: FloatArray) -> tuple[FloatArray, ...]:
    """Cofactors ``c00 c01 c02 c11 c12 c22`` and determinant of the symmetric matrices
    whose distinct entries ``a b c e f i`` are ``m[..., :6]``."""
    a, b, c, e, f, i = (m[..., k] for k in range(6))
    c00, c01, c02 = e * i - f * f, c * f - b * i, b * f - c * e
    c11, c12, c22 = a * i - c * c, b * c - a * f, a * e - b * b
    return c00, c01, c02, c11, c12, c22, a * c00 + b * c01 + c * c02


def _cramer(m: FloatArray, rhs: FloatArray) -> FloatArray:
    """Solve the symmetric 3x3 systems ``M x = rhs`` (``m``: :func:`_normal_equations`)
    by the cofactors (Cramer's rule): (..., 3); singular systems give non-finite values."""
    c00, c01, c02, c11, c12, c22, det = _cofactors(m)
    r0, r1, r2 = rhs[..., 0], rhs[..., 1], rhs[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_det = 1.0 / det
        return np.stack(
            [
                (c00 * r0 + c01 * r1 + c02 * r2) * inv_det,
                (c01 * r0 + c11 * r1 + c12 * r2) * inv_det,
                (c02 * r0 + c12 * r1 + c22 * r2) * inv_det,
            ],
            axis=-1,
        )


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


def linear_residuals(velocity: FloatArray, design: FloatArray, valid: BoolArray) -> FloatArray:
    """The residuals of :func:`fit_linear` alone (data minus model, m s-1; (S, R, G)).

    The same fit, without the standard errors and covariances the outlier screening does
    not use; the model of an undetermined (scan, gate) is 0.
    """
    design = np.nan_to_num(design)
    weight = valid.astype(float)
    inverse, _ = _safe_inverse(_normal_matrix(design, weight), weight.sum(axis=1))
    beta = _solve(np.nan_to_num(inverse), design, np.where(valid, velocity, 0.0))
    return velocity - _model(design, beta)


def ray_rows(
    values: FloatArray, valid: BoolArray, *, magnitude: bool = False
) -> tuple[FloatArray, FloatArray]:
    """The data of every (scan, gate) as a row of its rays: ``y`` (S, G, R), the values
    (``|values|`` when ``magnitude``) where ``valid`` and 0 elsewhere, and the 0/1
    weights ``used`` (S, G, R); both C-contiguous new arrays."""
    valid_rows = valid.transpose(0, 2, 1)
    used = np.array(valid_rows, dtype=float, order="C")
    y = np.array(values.transpose(0, 2, 1), dtype=float, order="C")
    if magnitude:
        np.abs(y, out=y)
    np.copyto(y, 0.0, where=~valid_rows)
    return y, used


def linear_start(
    velocity: FloatArray,
    design: FloatArray,
    valid: BoolArray,
    rows: tuple[FloatArray, FloatArray] | None = None,
    *,
    residuals: bool = True,
) -> tuple[BoolArray, FloatArray, FloatArray | None]:
    """``determined``, ``nan_to_num(beta)`` and the residuals of the least-squares fit
    of every (scan, gate) (:func:`fit_linear`, to round-off), without its residual
    variance and covariances; the model of an undetermined (scan, gate) is 0.

    ``rows`` is :func:`ray_rows` of ``velocity`` and ``valid`` when the caller holds it:
    the normal equations are then summed over contiguous rows of rays. ``residuals``
    False: None instead of the residuals (a caller that takes them as rows,
    :func:`row_residuals`).
    """
    design = np.nan_to_num(design)
    y, used = ray_rows(velocity, valid) if rows is None else rows
    n_scan, n_gate = y.shape[:2]
    ata = np.matmul(used, _design_outer(design)).reshape(n_scan, n_gate, 3, 3)
    inverse, determined = _safe_inverse(ata, used.sum(axis=-1))
    aty = np.matmul(y, design)
    beta = np.einsum("sgjk,sgk->sgj", np.nan_to_num(inverse), aty)
    beta = np.nan_to_num(np.where(determined[..., None], beta, np.nan))
    if not residuals:
        return determined, beta, None
    return determined, beta, velocity - _model(design, beta)


def row_residuals(y: FloatArray, design: FloatArray, beta: FloatArray) -> FloatArray:
    """``y - A beta`` of every (scan, gate) as rows of rays (S, G, R), in ``y``'s dtype.

    ``y``: the first of :func:`ray_rows` (0 where not valid, so that there the result
    is ``-A beta``); ``beta`` (S, G, 3) finite (m s-1).
    """
    a = np.nan_to_num(design).transpose(0, 2, 1).astype(y.dtype)
    model = np.matmul(beta.astype(y.dtype), a)
    return np.subtract(y, model, out=model)


def group_linear_residuals(
    velocity: FloatArray,
    design: FloatArray,
    valid: BoolArray,
    scans: NDArray[np.intp],
    gates: NDArray[np.intp],
) -> FloatArray:
    """:func:`linear_residuals` of the (scan, gate) groups ``(scans[i], gates[i])`` alone.

    Each group is fitted on its own rays (Smalikho (2020), eq. 1), as rows of rays, so
    that a few groups cost a few rows and not their scans' every gate.

    Returns
    -------
    ndarray, shape (N, R)
        Data minus model of every ray of each group (m s-1).
    """
    y = velocity[scans, :, gates]
    used = valid[scans, :, gates]
    weight = used.astype(float)[:, None, :]  # (N, 1, R)
    a = np.nan_to_num(design)[scans]  # (N, R, 3)
    m = np.matmul(weight, _design_outer(a))[:, 0].reshape(-1, 3, 3)
    inverse, _ = _safe_inverse(m, used.sum(axis=1))
    aty = np.matmul(weight * np.where(used, y, 0.0)[:, None, :], a)[:, 0]
    beta = np.einsum("njk,nk->nj", np.nan_to_num(inverse), aty)
    return y - np.einsum("nrk,nk->nr", a, beta)


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


def _arc_search_block(
    y: FloatArray, design: FloatArray, inverse: FloatArray, determined: BoolArray
) -> FloatArray:
    """:func:`homodyne_global_start` for one block of scans.

    With ``(A^T A)^-1 = F F^T`` (``F = V diag(sqrt(lambda))`` from the eigenvectors V
    and eigenvalues lambda, which never fails on a symmetric matrix),
    ``c^T (A^T A)^-1 c = |F^T c|^2`` and ``b = F (F^T c)``: the prefix sums are taken of
    ``F^T a_r y_r``, so that the cost of an arc is a sum of three squares.
    """
    n_scan, n_ray, n_gate = y.shape
    sym = np.where(determined[..., None, None], inverse, np.eye(3))
    eigenvalues, vectors = np.linalg.eigh(0.5 * (sym + np.swapaxes(sym, -1, -2)))
    factor = vectors * np.sqrt(np.maximum(eigenvalues, 0.0))[..., None, :]
    theta = np.arctan2(design[..., 0], design[..., 1])
    order = np.argsort(theta, axis=1, kind="stable")[..., None]
    a = np.take_along_axis(design, order, axis=1)  # (S, R, 3) in azimuth order
    ys = np.take_along_axis(y, order, axis=1)  # (S, R, G)
    # F^T a_r y_r for every gate: (S, R, G, 3)
    rotated = np.einsum("sgkj,srk->srgj", factor, a) * ys[..., None]
    prefix = np.zeros((n_scan, 2 * n_ray + 1, n_gate, 3))
    np.cumsum(np.concatenate([rotated, rotated], axis=1), axis=1, out=prefix[:, 1:])
    total = prefix[:, n_ray]  # F^T A^T y, (S, G, 3)
    best_gain = np.sum(total**2, axis=-1)  # the all-positive pattern
    best_length = np.zeros((n_scan, n_gate), dtype=np.int64)
    best_start = np.zeros((n_scan, n_gate), dtype=np.int64)
    for length in range(1, n_ray // 2 + 1):
        # s = +1 on the arcs [k, k + length), -1 elsewhere; complements give -b
        c = 2.0 * (prefix[:, length : length + n_ray] - prefix[:, :n_ray]) - total[:, None]
        gain = np.einsum("srgj,srgj->srg", c, c)
        k = np.argmax(gain, axis=1)
        top = np.take_along_axis(gain, k[:, None], axis=1)[:, 0]
        better = top > best_gain
        best_gain = np.where(better, top, best_gain)
        best_length = np.where(better, length, best_length)
        best_start = np.where(better, k, best_start)
    s_idx, g_idx = np.indices((n_scan, n_gate))
    arc = prefix[s_idx, best_start + best_length, g_idx] - prefix[s_idx, best_start, g_idx]
    c = np.where((best_length > 0)[..., None], 2.0 * arc - total, total)
    return np.einsum("sgjk,sgk->sgj", factor, c)


def homodyne_global_start(
    y: FloatArray, design: FloatArray, inverse: FloatArray, determined: BoolArray
) -> FloatArray:
    """The global minimiser of ``sum (|V_r| - |A beta|)^2`` for rays at one elevation.

    On a cone of elevation ``phi``, ``A beta = w sin(phi) + cos(phi) V_h cos(theta -
    theta_w)`` (Smalikho (2020), eq. 1) is positive on one arc of azimuths centred on
    ``theta_w`` and negative on the rest (or of one sign everywhere). For any ``beta``
    of sign pattern ``s``, ``sum (|V_r| - |A beta|)^2 = sum (s |V_r| - A beta)^2`` is at
    least the least-squares cost of the linear fit of ``s |V_r|``,
    ``C(s) = |y|^2 - c_s^T (A^T A)^-1 c_s`` with ``c_s = A^T (s y)``; and the fit
    ``b_s`` of the arc ``s`` of least ``C`` has ``|A b_s|``-cost at most ``C(s)``. So
    the least ``C`` over all arcs is the global minimum, reached at ``b_s``, whatever
    the wind: no start grid can miss it (Gauss-Newton from half-circle patterns
    converged to v = 1.16, w = 1.13 for 8 rays, phi = 52 deg, u = 0, v = 2, w = 0.75).
    With the rays sorted by azimuth, ``c_s = 2 sum_arc a_r y_r - A^T y`` comes from
    prefix sums, so each of the ``R^2 / 2`` arcs (their complements give ``-b_s``, of
    equal cost) costs O(1).

    Parameters
    ----------
    y : ndarray, shape (S, R, G)
        ``|V_r|`` (m s-1), 0 for unused entries.
    design : ndarray, shape (S, R, 3)
        Beam unit vectors (finite; padding rows 0).
    inverse : ndarray, shape (S, G, 3, 3)
        ``(A^T A)^-1`` over the used rays.
    determined : ndarray of bool, shape (S, G)
        Cells whose ``inverse`` is a valid (positive definite) inverse; elsewhere the
        result is meaningless (and masked by the caller).

    Returns
    -------
    ndarray, shape (S, G, 3)
        ``b_s`` (m s-1), with an arbitrary overall sign.
    """
    n_scan, n_ray, n_gate = y.shape
    step = max(1, HOMODYNE_BLOCK_ELEMENTS // max(n_ray * n_gate, 1))
    out = np.empty((n_scan, n_gate, 3))
    for lo in range(0, n_scan, step):
        part = slice(lo, lo + step)
        out[part] = _arc_search_block(y[part], design[part], inverse[part], determined[part])
    return out


def fit_homodyne(magnitude: FloatArray, design: FloatArray, valid: BoolArray) -> BatchedFit:
    """Fit ``|V_r| = |A beta|`` (homodyne cw lidar; Wagner et al. (DTU)) for every (scan, gate).

    Started at the global minimum over the arc sign patterns
    (:func:`homodyne_global_start`), then Gauss-Newton on ``|A beta|``: each step is
    the linear fit of ``sign(A beta) |V_r|`` (``J^T J = A^T A``), iterated until no sign
    changes; each step can only lower the cost, so the fixed point keeps the global
    minimum (and is reached in one or two steps). ``beta`` is returned with an
    arbitrary overall sign (see :func:`cwproc.stages.vad.resolve_homodyne_ambiguity`).

    Parameters
    ----------
    magnitude : ndarray, shape (S, R, G)
        Measured ``|V_r|`` (m s-1); the sign of the input is ignored.
    design : ndarray, shape (S, R, 3)
        :func:`cwproc.physics.geometry.beam_unit_vector` of each ray.
    valid : ndarray of bool, shape (S, R, G)

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
    start = homodyne_global_start(y, design, inv0, determined)
    beta, converged = _sign_iterations(y, design, weight, inv0, start)
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
    start: tuple[BoolArray, FloatArray] | None = None,
    rows: tuple[FloatArray, FloatArray] | None = None,
    as_rows: bool = False,
) -> tuple[FloatArray, FloatArray]:
    """Residuals about a least-absolute-deviations (L1) VAD fit of every (scan, gate).

    A robust first fit for outlier screening: with a balanced azimuth design the L1 fit
    is not pulled by a minority of wild radial velocities, unlike least squares. Solved by
    iteratively reweighted least squares, weights ``1 / max(|r|, floor)``, started from
    :func:`fit_scans`; for homodyne data each step re-assigns the signs as in
    :func:`fit_homodyne`.

    Each (scan, gate) stops on its own: once all of its coefficients changed by less than
    ``tolerance`` in a step it leaves the batch, and the cells still moving are packed
    into fewer columns, so the work follows the cells that need it (on the 180-ray scans
    of a simulated day a cell stops after 5.7 steps on average, where a stop of the whole
    batch at the slowest cell took 19.5). Stopping a cell at a step below ``tolerance`` is
    not being within ``tolerance`` of the limit: IRLS converges linearly and slowly where
    the L1 cost is flat, and on those scans the stopped coefficients lie up to 0.16 m s-1
    (90 % within 0.03 m s-1) from a fit iterated 400 times, where the batch stopped at
    its slowest cell lay up to 0.1 m s-1 from it; their mean absolute residual exceeds
    the iterated fit's by less than 1e-3 m s-1 (0.5 %) in every cell. The outlier flags
    that follow (:mod:`cwproc.stages.qc`) differ from those of the whole-batch stop in
    about 3 % of the flagged rays, those whose residual lies at the threshold (on the
    simulated day 220 of 34.6 million rays and gates, 7274 flagged before, 7202 after).

    The iterations run in float32 (data, weights and the sums of the normal equations;
    the 3x3 solutions in float64): the sums of 180 rays round to about 1e-6 of the
    coefficients, far below ``tolerance``, at half the memory traffic; the returned
    residuals are computed in float64 from the final coefficients (float32 with
    ``as_rows``: the outlier test's medians and thresholds then round at 1e-7 relative,
    which changed no flag of the simulated day).

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
        Most IRLS iterations of a cell.
    floor : float, optional
        Smallest residual (m s-1) in the weights.
    tolerance : float, optional
        A cell stops when all of its coefficients changed by less than this in a step
        (m s-1); screening needs residuals only to a fraction of the noise.
    start : (ndarray of bool (S, G), ndarray (S, G, 3)), optional
        ``determined`` and ``nan_to_num(beta)`` of the start (:func:`linear_start`) when
        the caller holds them (not written to); None: computed here.
    rows : (ndarray (S, G, R), ndarray (S, G, R)), optional
        :func:`ray_rows` of ``values`` and ``valid`` (``magnitude=homodyne``), float64
        or float32, when the caller holds them (not written to); None: computed here.
    as_rows : bool, optional
        Linear model only: the residuals as float32 rows of rays (S, G, R) (for a
        median along the contiguous axis; where ``valid`` is false they are
        ``-A beta``), made from the iterations' float32 data.

    Returns
    -------
    (beta, residuals) : ndarray (S, G, 3), ndarray (S, R, G)
        The L1 coefficients (m s-1; NaN where not determined) and data minus model
        (homodyne: ``|V_r| - |A beta|``) (m s-1).
    """
    rows = ray_rows(values, valid, magnitude=homodyne) if rows is None else rows
    if start is not None:
        ok, beta = start[0], start[1].copy()
    elif homodyne:
        first = fit_homodyne(values, design, valid)
        ok, beta = first.determined, np.nan_to_num(first.beta)
    else:
        ok, beta, _ = linear_start(values, design, valid, rows)
    design = np.nan_to_num(design)
    rows32 = rows[0].astype(np.float32, copy=False), rows[1].astype(np.float32, copy=False)
    batch = _IrlsBatch.of(rows32, design, beta, ok)
    for _ in range(iterations):
        if batch is None:
            break
        moving = batch.step(homodyne, floor, tolerance)
        batch = batch.narrowed(moving, beta)
    if batch is not None:
        batch.write(beta)
    if as_rows and not homodyne:
        return np.where(ok[..., None], beta, np.nan), row_residuals(rows32[0], design, beta)
    model = _model(design, beta)
    residuals = np.abs(values) - np.abs(model) if homodyne else values - model
    return np.where(ok[..., None], beta, np.nan), residuals


@dataclass
class _IrlsBatch:
    """The (scan, gate) cells of :func:`fit_least_absolute` still iterated, packed.

    ``scans`` (S') are the scans with a moving cell and ``gates`` (S', K) the gate of each
    column: the scan's moving cells in gate order, then padding (``pad``), which
    repeats a moving gate with zero weight. ``idle`` (S', K) marks the columns whose
    step is discarded: padding and the cells that stopped since the batch was packed.
    ``y``, ``used`` (S', K, R: a cell's rays contiguous), ``design`` (S', 3, R),
    ``pairs`` (S', R, 6) and ``beta`` (S', K, 3) are the cells' data.
    """

    scans: NDArray[np.intp]
    gates: NDArray[np.intp]
    pad: BoolArray
    idle: BoolArray
    y: FloatArray
    used: FloatArray
    design: FloatArray
    pairs: FloatArray
    beta: FloatArray

    @classmethod
    def of(
        cls,
        rows: tuple[FloatArray, FloatArray],
        design: FloatArray,
        beta: FloatArray,
        ok: BoolArray,
    ) -> _IrlsBatch | None:
        """The batch of the determined cells ``ok`` (None if there is none); ``rows``:
        :func:`ray_rows` as float32 (not written to)."""
        y, used = rows
        none = np.zeros(ok.shape, dtype=bool)
        whole = cls(
            scans=np.arange(y.shape[0]),
            gates=np.broadcast_to(np.arange(y.shape[1]), ok.shape),
            pad=none,
            idle=none,
            y=y,
            used=used,
            design=np.ascontiguousarray(design.transpose(0, 2, 1), dtype=np.float32),
            pairs=_design_pairs(design).astype(np.float32),
            beta=beta.copy(),
        )
        return whole.narrowed(ok, beta)

    def write(self, beta: FloatArray) -> None:
        """Copy the coefficients of the batch's cells into ``beta`` (S, G, 3)."""
        cell = ~self.pad
        scans = np.broadcast_to(self.scans[:, None], cell.shape)
        beta[scans[cell], self.gates[cell]] = self.beta[cell]

    def narrowed(self, moving: BoolArray, beta: FloatArray) -> _IrlsBatch | None:
        """The batch of the cells ``moving`` (S', K) of this one, or None if none moves.

        When packing would leave at most ``PACK_FRACTION`` of the columns, the moving
        cells are packed anew (the coefficients of this batch written to ``beta``
        first); otherwise this batch goes on with the stopped cells idle.
        """
        moving = moving & ~self.idle
        keep = np.flatnonzero(moving.any(axis=1))
        if keep.size == 0:
            self.write(beta)
            return None
        count = moving[keep].sum(axis=1)
        width = int(count.max())
        if keep.size * width > PACK_FRACTION * moving.size:
            self.idle = ~moving
            return self
        self.write(beta)
        # the moving columns of each kept scan first, in gate order; then padding
        column = np.argsort(~moving[keep], axis=1, kind="stable")[:, :width]
        pad = np.arange(width) >= count[:, None]
        column = np.where(pad, column[:, :1], column)
        rows = keep[:, None]
        used = self.used[rows, column]
        used[pad] = 0.0
        return _IrlsBatch(
            scans=self.scans[keep],
            gates=self.gates[rows, column],
            pad=pad,
            idle=pad,
            y=self.y[rows, column],
            used=used,
            design=self.design[keep],
            pairs=self.pairs[keep],
            beta=self.beta[rows, column],
        )

    def step(self, homodyne: bool, floor: float, tolerance: float) -> BoolArray:
        """One IRLS step of every cell (``beta`` updated; ``idle`` cells keep theirs);
        the cells with a coefficient that changed by ``tolerance`` or more (S', K)."""
        model = np.matmul(self.beta.astype(np.float32), self.design)  # A beta, (S', K, R)
        target = self.y * np.where(model >= 0, 1.0, -1.0).astype(np.float32) if homodyne else self.y
        weight = np.abs(np.subtract(target, model, out=model), out=model)
        np.divide(self.used, np.maximum(weight, np.float32(floor), out=weight), out=weight)
        # the distinct entries of sum_r w a_j a_k and sum_r w y a_j (_normal_equations)
        m = np.matmul(weight, self.pairs)
        rhs = np.matmul(np.multiply(weight, target, out=weight), self.design.transpose(0, 2, 1))
        new = _cramer(m.astype(float), rhs.astype(float))
        np.copyto(new, self.beta, where=self.idle[..., None])
        moving = ~(np.max(np.abs(new - self.beta), axis=-1) < tolerance)
        self.beta = new
        return moving


def fit_scans(
    velocity: FloatArray, design: FloatArray, valid: BoolArray, *, homodyne: bool
) -> BatchedFit:
    """:func:`fit_homodyne` when ``homodyne``, else :func:`fit_linear`."""
    if homodyne:
        return fit_homodyne(velocity, design, valid)
    return fit_linear(velocity, design, valid)
