"""Share of sigma_V^2 the block-mean VAD wind removes from the radial-velocity deviations.

The deviations ``V'_L`` from the VAD fit (Smalikho (2020), eqs. 1-2) miss the part of
the variance the fitted wind takes: ``tr(H B)/M`` of the fit's hat matrix ``H`` and the
correlation tensor ``B`` of the isotropic field (Banakh et al. (1999), eqs. 15-16) at
the beams, seen at their own times in the field the wind carries (Smalikho (2020),
eq. 3). :func:`removed_share_curve` and :func:`share_on_curve` for full circles (kept
on disk by the table store, :func:`cwproc.tables.removed_share.mean_removed_share`),
:func:`sector_removed_share` for sectors and gaps (:func:`partial_circle`). Pure numpy:
no files, no environment.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from cwproc.physics import spectra
from cwproc.physics.atable_interp import N_BINS, azimuth_nodes

#: nodes of mu = U/V_s of :func:`share_on_curve` (linear interpolation between them)
REMOVED_SHARE_MU = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0])


#: wind directions (from the scan's first ray) averaged in :func:`share_on_curve`
_REMOVED_SHARE_DIRECTIONS = 4


#: nodes of ``x = R'/L_V`` of :func:`removed_share_curve`
_CURVE_X = np.geomspace(1e-2, 1e2, 25)
#: point beams of the full circle of :func:`removed_share_curve`
_CURVE_BEAMS = 48


def curve_parameters(phi_deg: float, model: str) -> dict:
    """Every parameter of :func:`removed_share_curve` but the code (the curve's key)."""
    return {
        "phi_deg": phi_deg,
        "model": model,
        "x": _CURVE_X.tolist(),
        "mu": REMOVED_SHARE_MU.tolist(),
        "n_az": _CURVE_BEAMS,
    }


def curve_log_x() -> np.ndarray:
    """``log x`` of the nodes of :func:`removed_share_curve`, ``x = R'/L_V``."""
    return np.log(_CURVE_X)


def valid_curve(share: np.ndarray | None) -> bool:
    """Whether ``share`` has the shape and finite values of :func:`removed_share_curve`."""
    shape = (REMOVED_SHARE_MU.size, _CURVE_X.size)
    return share is not None and share.shape == shape and bool(np.isfinite(share).all())


def removed_share_curve(phi_deg: float, model: str) -> tuple[np.ndarray, np.ndarray]:
    """``(log x, r(mu, x))`` of :func:`share_on_curve` on 25 nodes of ``x = R'/L_V``.

    ``tr(H B)/M`` of the VAD hat matrix ``H = (1 + 2 cos(theta_i - theta_j))/M`` of a
    full circle of 48 point beams and the correlation tensor ``B`` of the frozen field
    at the probes' positions in the field's frame, ``R' e(theta_m) - U t_m``: the rays
    follow each other over one scan period, so the wind carries the field ``mu R'
    theta_m`` along its direction (Smalikho (2020), eq. 3: ``U T = 2 pi mu R'``);
    averaged over :data:`_REMOVED_SHARE_DIRECTIONS` wind directions.
    """
    x = _CURVE_X
    n_az = _CURVE_BEAMS
    theta = 2.0 * np.pi * np.arange(n_az) / n_az
    ph = math.radians(phi_deg)
    s = np.stack(
        [np.full(n_az, math.sin(ph)), math.cos(ph) * np.cos(theta), math.cos(ph) * np.sin(theta)],
        axis=-1,
    )
    dot = s @ s.T
    hat = (1.0 + 2.0 * np.cos(theta[:, None] - theta[None, :])) / n_az**2
    circle = np.stack([np.zeros(n_az), np.cos(theta), np.sin(theta)], -1)
    share = np.zeros((REMOVED_SHARE_MU.size, x.size))
    for i, mu in enumerate(REMOVED_SHARE_MU):
        directions = 1 if mu == 0 else _REMOVED_SHARE_DIRECTIONS
        for k in range(directions):
            a = 2.0 * np.pi * k / directions
            wind = np.array([0.0, math.cos(a), math.sin(a)])
            pos = x[:, None, None] * (circle - mu * theta[:, None] * wind)[None]
            r_vec = pos[:, :, None, :] - pos[:, None, :, :]  # (x, i, j, 3)
            r = np.linalg.norm(r_vec, axis=-1)
            # each distinct separation once (r_ij = r_ji; at mu 0 a few per x)
            r_u, at = np.unique(r, return_inverse=True)
            f_u, g_u = spectra.correlation_functions(r_u, model, 1.0)
            f, g = f_u[at].reshape(r.shape), g_u[at].reshape(r.shape)
            unit = np.where(r[..., None] > 0, r_vec / np.where(r > 0, r, 1.0)[..., None], 0.0)
            proj_i = np.einsum("xijk,ik->xij", unit, s)
            proj_j = np.einsum("xijk,jk->xij", unit, s)
            b = g * dot[None] + (f - g) * proj_i * proj_j
            share[i] += np.einsum("xij,ij->x", b, hat) / directions
    return np.log(x), share


def share_on_curve(
    curve: tuple[np.ndarray, np.ndarray], ratio: np.ndarray, mu: np.ndarray | float = 0.0
) -> np.ndarray:
    """Share of sigma_V^2 the scan-mean (VAD) wind takes from one scan's V'_L.

    ``tr(H B)/(M sigma_V^2)`` of a full circle of point beams, Banakh et al. (1999),
    eqs. 15-16 with the isotropic tensor of the curve's model, the rays seen at their own
    times in the field carried by the wind: ``curve = (log x, r(mu, x))`` of
    :func:`removed_share_curve`, interpolated at ``ratio = R'/L_V`` (linear in
    ``log x``) and ``mu = U/V_s`` (linear). The block mean of N independent scans
    removes this divided by N. The probe volume is neglected (the share is carried by
    scales of the circle, far above the probe). Transport matters: on exact 24-ray
    statistics at ``mu = 3`` (R'/L_V = 0.71) the block-mean wind removed 2.4 % of
    sigma_V^2, the frozen circle predicts 5.0 %; the overestimate biased the variance
    condition and eps 8 % low.
    """
    log_x, share = curve
    lx = np.log(np.clip(ratio, 1e-2, 1e2))
    m = np.clip(np.nan_to_num(np.asarray(mu, float), nan=0.0), 0.0, REMOVED_SHARE_MU[-1])
    lx, m = np.broadcast_arrays(lx, m)
    j = np.clip(
        np.searchsorted(REMOVED_SHARE_MU, m, side="right") - 1, 0, REMOVED_SHARE_MU.size - 2
    )
    w = (m - REMOVED_SHARE_MU[j]) / (REMOVED_SHARE_MU[j + 1] - REMOVED_SHARE_MU[j])
    # the two bracketing mu rows interpolated in lg(R'/L_V) where each is needed only
    # (not every row everywhere: that held a (mu node, time, height, L_V) array)
    lo = np.empty(lx.shape)
    hi = np.empty(lx.shape)
    for k in np.unique(j):
        at = j == k
        lo[at] = np.interp(lx[at], log_x, share[k])
        hi[at] = np.interp(lx[at], log_x, share[k + 1])
    return (1.0 - w) * lo + w * hi


#: nodes of x = R'/L_V of :func:`sector_removed_share` (log-log interpolation)
_SECTOR_X = np.geomspace(1e-2, 1e2, 9)


@functools.lru_cache(maxsize=4)
def correlation_curve(model: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(ln r, f, g)``: normalised correlations of ``model`` at ``r/L_V`` 1e-5 to 1e3."""
    r = np.geomspace(1e-5, 1e3, 400)
    f, g = spectra.correlation_functions(r, model, 1.0)
    return np.log(r), f, g


def interp_log_scale(grid_m: np.ndarray, values: np.ndarray, query_m: np.ndarray) -> np.ndarray:
    """Linear interpolation in ``log L`` of ``values (cells, K)`` at ``query_m (cells, k)``."""
    lg = np.log(grid_m)
    pos = (np.log(query_m) - lg[0]) / (lg[1] - lg[0])
    i0 = np.clip(np.floor(np.nan_to_num(pos, nan=0.0)).astype(int), 0, lg.size - 2)
    frac = pos - i0
    v0 = np.take_along_axis(values, i0, axis=1)
    v1 = np.take_along_axis(values, i0 + 1, axis=1)
    return v0 + (v1 - v0) * frac


def _empty_runs(occupied: np.ndarray) -> np.ndarray:
    """``(cells, N_BINS)`` number of empty nodes just before each node in scan order.

    The scan moves towards decreasing node angle (``theta = sign (wind_to - beta)``).
    """

    run = np.zeros(occupied.shape, dtype=int)
    still = np.ones(occupied.shape, dtype=bool)
    for j in range(1, N_BINS):
        still &= ~np.roll(occupied, -j, axis=-1)
        run += still
    return run


def partial_circle(weights: np.ndarray, step_deg: np.ndarray) -> np.ndarray:
    """``(cells,)`` whether the pairs present leave out a sector wider than the scan's step.

    An empty stretch of azimuth nodes wider than ``max(2.5 dtheta, 20 deg)``: a sector
    scan or a gap (a regular scan leaves at most ``2 dtheta`` empty, where the last and
    the first ray of a scan make no pair).
    """

    w = np.asarray(weights, float)
    known = np.all(np.isfinite(w), axis=-1) & (np.nan_to_num(w).sum(-1) > 0)
    runs = _empty_runs(np.nan_to_num(w) > 1e-12).max(axis=-1, initial=0)
    widest = runs * (360.0 / N_BINS)
    return known & (widest > np.maximum(2.5 * np.asarray(step_deg, float), 20.0))


def _scan_start_phase(occupied: np.ndarray) -> np.ndarray:
    """``(cells, N_BINS)`` scan angle (rad) travelled since the scan's first node.

    The scan starts at the occupied node that follows the longest run of empty nodes.
    """

    run = _empty_runs(occupied)
    start = np.argmax(np.where(occupied, run, -1), axis=-1)
    th = azimuth_nodes()
    return np.mod(th[start][:, None] - th[None, :], 2.0 * np.pi)


def sector_removed_share(
    weights: np.ndarray,
    ratio: np.ndarray,
    mu: np.ndarray,
    interval: np.ndarray,
    n_scans: np.ndarray,
    phi_deg: float,
    model: str,
    chunk: int = 8,
) -> np.ndarray:
    """Share of sigma_V^2 the block-mean VAD wind takes from V'_L of a sector or gappy scan.

    Each scan's VAD fit over the azimuths present (node weights ``w_k``,
    ``pair_azimuth_weights``) projects with ``h_kl = X_k^T (sum_j w_j X_j X_j^T)^-1
    X_l``, ``X = (1, cos beta, sin beta)``; the block mean of N such fits removes
    ``[N S_0 + 2 sum_m (N - m) S_m] / N^2`` with ``S_m = sum_kl w_k w_l h_kl
    b_kl(m) / sum w`` and ``b_kl(m)`` the correlation of point beams k and l (Banakh
    et al. (1999), eqs. 15-16, isotropic tensor of ``model``) in the field carried by
    the wind: within a scan the rays follow each other (``mu R'`` per radian scanned,
    Smalikho (2020), eq. 3), and scan ``n + m`` is ``m U T_int`` further on. A full
    circle of independent scans gives :func:`share_on_curve` over N. Exact
    statistics of a 90 deg sector scan (45 rays, 12 s apart): the fit removes 7.7 % of
    sigma_V^2 per scan, and, the scans being 1-2 L_V apart, 11-18 % of it in the block
    at mu 1-0.5 (the full circle: 4.6 %).

    Parameters
    ----------
    weights : numpy.ndarray
        ``(cells, N_BINS)`` node weights; rows that are NaN give NaN (the caller keeps
        :func:`share_on_curve` there and for full circles, :func:`partial_circle`).
    ratio : numpy.ndarray
        ``(cells, k)`` values of ``R'/L_V``.
    mu, interval, n_scans : numpy.ndarray
        ``(cells,)``: ``U/V_s``, the time between scan starts over ``T_scan`` (the
        full-circle period of :func:`cwproc.stages.epsilon.estimate_epsilon`), scans per block.
    """

    out = np.full(ratio.shape, np.nan)
    w = np.nan_to_num(np.asarray(weights, float))
    cells = np.nonzero(np.all(np.isfinite(weights), axis=-1) & (w.sum(-1) > 0))[0]
    if cells.size == 0:
        return out
    log_r, f_c, g_c = correlation_curve(model)
    th = azimuth_nodes()
    beta = -th  # wind towards beta = 0; the frozen statistics are mirror-symmetric
    ph = math.radians(phi_deg)
    design = np.stack([np.ones(N_BINS), np.cos(beta), np.sin(beta)], -1)
    circle = np.stack([np.cos(beta), np.sin(beta), np.zeros(N_BINS)], -1)
    beam = np.stack([math.cos(ph) * circle[:, 0], math.cos(ph) * circle[:, 1]], -1)
    beam = np.concatenate([beam, np.full((N_BINS, 1), math.sin(ph))], -1)
    wind = np.array([1.0, 0.0, 0.0])
    n_max = int(np.nanmax(n_scans[cells]))
    m = np.arange(n_max)
    for i in range(0, cells.size, chunk):
        c = cells[i : i + chunk]
        wc = w[c]
        gram = np.einsum("ck,ka,kb->cab", wc, design, design)
        h = np.einsum("ka,cab,lb->ckl", design, np.linalg.pinv(gram), design)
        hw = h * wc[:, :, None] * wc[:, None, :] / wc.sum(-1)[:, None, None]
        phase = _scan_start_phase(wc > 1e-12)
        pos = circle[None] - (mu[c][:, None] * phase)[..., None] * wind  # (c, k, 3), R' units
        # only the occupied nodes (a sector's few): the others have no weight
        occupied = wc > 1e-12
        idx = np.argsort(~occupied, axis=1, kind="stable")[:, : occupied.sum(1).max()]
        rows = np.arange(c.size)[:, None]
        hw, pos, bc = (
            hw[rows[..., None], idx[:, :, None], idx[:, None, :]],
            pos[rows, idx],
            beam[idx],
        )
        shift = (mu[c] * 2.0 * np.pi * interval[c])[:, None] * m[None]  # (c, m)
        r_vec = pos[:, :, None, None, :] - pos[:, None, :, None, :]
        r_vec = r_vec - shift[:, None, None, :, None] * wind  # (c, k, l, m, 3)
        r = np.linalg.norm(r_vec, axis=-1)
        unit = r_vec / np.where(r > 0, r, 1.0)[..., None]
        proj = np.einsum("cklmi,cki->cklm", unit, bc) * np.einsum("cklmi,cli->cklm", unit, bc)
        dot = np.einsum("cki,cli->ckl", bc, bc)[..., None]
        lr = np.log(np.maximum(r[..., None] * _SECTOR_X, 1e-5))  # (c, k, l, m, x)
        f, g = np.interp(lr, log_r, f_c), np.interp(lr, log_r, g_c)
        s_m = np.einsum("ckl,cklmx->cmx", hw, g * dot[..., None] + (f - g) * proj[..., None])
        n = n_scans[c][:, None]
        mult = np.where(m[None] == 0, n, 2.0 * np.clip(n - m[None], 0.0, None)) / n**2
        share = np.einsum("cm,cmx->cx", mult, s_m)
        query = np.clip(ratio[c], _SECTOR_X[0], _SECTOR_X[-1])  # log-log interpolation
        out[c] = np.exp(interp_log_scale(_SECTOR_X, np.log(np.maximum(share, 1e-12)), query))
    return out


#: nodes of the correlation table per node step of :data:`REMOVED_D_X` (in ``ln r``)
_CURVE_PER_X = 16


@functools.lru_cache(maxsize=4)
def _correlation_nodes(model: str) -> tuple[float, float, np.ndarray, np.ndarray]:
    """``(ln r_0, d ln r, G, dG)``: ``g`` and ``f - g`` of ``model`` at ``r x`` for the
    ``x`` of :data:`REMOVED_D_X` on a grid of ``r`` (units of ``R'``, 1e-6 to 1e4) uniform
    in ``ln r``.

    ``G`` is ``(r node, 2, x)`` and ``dG`` its step to the next ``r`` node (float32): the
    step is that of :data:`REMOVED_D_X` over :data:`_CURVE_PER_X`, so that the ``x``
    nodes of a separation share one row of the table.
    """
    step = math.log(REMOVED_D_X[1] / REMOVED_D_X[0]) / _CURVE_PER_X
    lo = math.log(1e-6)
    n = math.ceil((math.log(1e4) - lo) / step) + 2
    lr = lo + step * np.arange(n)[:, None] + np.log(REMOVED_D_X)[None, :]
    f, g = spectra.correlation_functions(np.exp(lr), model, 1.0)
    table = np.stack([g, f - g], 1)  # (r, 2, x)
    return lo, step, table.astype(np.float32), np.diff(table, axis=0).astype(np.float32)


def _point_correlation(
    p: np.ndarray, q: np.ndarray, sp: np.ndarray, sq: np.ndarray, model: str
) -> np.ndarray:
    """``(..., x)``: correlation of point beams ``sp`` at ``p`` and ``sq`` at ``q`` (R' units).

    ``g(r) s_p.s_q + [f(r) - g(r)] (s_p.e)(s_q.e)``, ``e`` along ``p - q``: Banakh et al.
    (1999), eqs. 15-16 with the isotropic tensor of ``model`` at ``r/L_V = |p - q| x`` for
    each ``x`` of :data:`REMOVED_D_X` (linear in ``ln r`` between the nodes of
    :func:`_correlation_nodes`; float32).
    """
    lo, step, table, slope = _correlation_nodes(model)
    r_vec = p - q
    r = np.linalg.norm(r_vec, axis=-1)
    unit = r_vec / np.where(r > 0, r, 1.0)[..., None]
    proj = np.sum(unit * sp, -1) * np.sum(unit * sq, -1)
    dot = np.sum(sp * sq, -1)
    with np.errstate(divide="ignore"):
        pos = np.clip(np.nan_to_num((np.log(r) - lo) / step, neginf=0.0), 0.0, slope.shape[0] - 1)
    i0 = np.floor(pos).astype(int)
    frac = (pos - i0).astype(np.float32)[..., None]
    weights = np.stack(np.broadcast_arrays(dot, proj), -1).astype(np.float32)  # (..., 2)
    b = np.einsum("...k,...kx->...x", weights, table[i0] + frac[..., None] * slope[i0])
    return np.where((r < 1e-6)[..., None], dot[..., None], b)  # the same point: s_p.s_q


#: rays per scan beyond which :func:`sector_removed_d` leaves D(l) alone and
#: :func:`circle_removed_d` takes the removal of a circle of this many rays at the same
#: lag angles (the cost of a configuration grows as the square of the rays)
MAX_SECTOR_RAYS = 60

#: nodes of mu = U/V_s of the removal in D(l) (:func:`_removed_d_grid`; linear
#: interpolation): dense below 1, where the scans of a block decorrelate (their VAD winds
#: are ``2 pi mu R' T_int/T_scan`` apart)
REMOVED_D_MU = np.array([0.0, 0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0, 1.4, 2.0, 3.0, 5.0, 10.0])

#: nodes of x = R'/L_V of the removal in D(l) (log-log interpolation: within 4 % of the
#: direct value between the nodes, 11-15 % with the 9 nodes of :data:`_SECTOR_X`)
REMOVED_D_X = np.geomspace(1e-2, 1e2, 17)

#: wind directions (from the scan's first ray) averaged in :func:`circle_removed_d`
CIRCLE_DIRECTIONS = 8


def _block_correlation(
    beta: np.ndarray,
    phase: np.ndarray,
    mu: float,
    n_scans: int,
    interval: float,
    phi_deg: float,
    model: str,
    frozen_at_rest: bool,
) -> np.ndarray:
    """``(i, j, x)``: block-mean correlation of ray ``i`` of a scan and ray ``j`` of the block.

    ``sum_m (N - |m|)/N^2 b_ij(m)``, ``b_ij(m)`` the correlation (over ``sigma_V^2``) of
    point beam ``i`` of scan ``n`` and ``j`` of scan ``n + m`` (Banakh et al. (1999), eqs.
    15-16), each seen at its own time in the field the wind (towards ``+x``) carries:
    ``mu R'`` per radian scanned and ``2 pi mu R' T_int/T_scan`` per scan (Smalikho (2020),
    eq. 3). ``beta`` ``(d, i)``: ray azimuths (rad) from the wind-to direction for ``d``
    wind directions (averaged); ``phase`` ``(i,)``: scan angle (rad) from the first ray.
    ``b_ij(-m) = b_ji(m)`` (stationarity): only ``m >= 0`` are evaluated. At ``mu = 0``
    the scans are the same field (``frozen_at_rest``) or independent (the no-transport
    limit of Smalikho (2020), where the field renews between scans).
    """
    ph = math.radians(phi_deg)
    wind = np.array([1.0, 0.0, 0.0])
    pos = np.stack([np.cos(beta), np.sin(beta), np.zeros(beta.shape)], -1)
    pos = pos - (mu * phase)[None, :, None] * wind  # (d, i, 3), R' units
    beam = np.stack(
        [
            math.cos(ph) * np.cos(beta),
            math.cos(ph) * np.sin(beta),
            np.full(beta.shape, math.sin(ph)),
        ],
        -1,
    )
    m = np.arange(n_scans if mu > 0 else 1)
    shift = (mu * 2.0 * np.pi * interval * m)[:, None, None, None] * wind  # (m, 1, 1, 3)
    b = _point_correlation(
        pos[:, None, :, None] - shift,
        pos[:, None, None, :],
        beam[:, None, :, None],
        beam[:, None, None, :],
        model,
    ).mean(axis=0)  # (m, i, j, x): ray i of scan n + m against ray j of scan n
    if mu == 0:
        return b[0] if frozen_at_rest else b[0] / n_scans
    later = np.einsum("m,mijx->ijx", (n_scans - m[1:]) / n_scans**2, b[1:])
    return b[0] / n_scans + later + np.swapaxes(later, 0, 1)


def _lag_shares(hat: np.ndarray, rho: np.ndarray, n_lags: int) -> np.ndarray:
    """``(x, 1 + n_lags)``: the variance's share, then ``(2 C - Q)/sigma_V^2`` of each lag.

    ``C = E[(V_a - V_b)(P_a - P_b)]``, ``Q = E[(P_a - P_b)^2]`` with ``P = H <V>_N`` the
    block-mean VAD wind at the rays (``hat`` the projection of one scan, ``rho`` of
    :func:`_block_correlation`), averaged over the pairs ``l`` rays apart within a scan
    (not wrapping round). Column 0: ``E[2 V_a P_a - P_a^2]/sigma_V^2`` over the rays,
    ``tr(H rho)/M`` (``H`` a symmetric projection, ``rho`` symmetric).
    """
    out = np.zeros((rho.shape[-1], n_lags + 1))
    out[:, 0] = np.einsum("ij,jix->x", hat, rho) / hat.shape[0]
    for li in range(min(n_lags, hat.shape[0] - 1)):
        a = np.arange(hat.shape[0] - li - 1)
        b = a + li + 1
        u = hat[a] - hat[b]  # (pairs, j): P_a - P_b per V_j
        cross = np.einsum("pj,pjx->px", u, rho[a] - rho[b])
        quad = np.einsum("pj,pk,jkx->px", u, u, rho)
        out[:, li + 1] = np.mean(2.0 * cross - quad, axis=0)
    return out


def _removed_d_grid(*configuration: Any) -> np.ndarray:
    """``(mu, x, n_lags)``: the removal in D(l) of :func:`_removed_grids`."""
    return _removed_grids(*configuration)[..., 1:]


@functools.lru_cache(maxsize=256)
def _removed_grids(
    phase: tuple[float, ...],
    offsets: tuple[float, ...],
    n_lags: int,
    n_scans: int,
    interval: float,
    phi_deg: float,
    model: str,
    frozen_at_rest: bool,
) -> np.ndarray:
    """``(mu, x, 1 + n_lags)``: removal in the variance, then in D(l), of one configuration.

    :data:`REMOVED_D_MU` x :data:`REMOVED_D_X`; rays at scan angles ``phase`` (rad from the
    first ray), whose azimuth from the wind-to direction is each of ``offsets`` (averaged:
    one for a sector, :data:`CIRCLE_DIRECTIONS` for a circle); ``frozen_at_rest`` as
    :func:`_block_correlation`. Cached per configuration.
    """
    ph = np.asarray(phase)
    beta = np.asarray(offsets)[:, None] + ph[None, :]
    design = np.stack([np.ones(ph.size), np.cos(ph), np.sin(ph)], -1)  # H: rotation-invariant
    hat = design @ np.linalg.pinv(design.T @ design) @ design.T
    grid = np.stack(
        [
            _lag_shares(
                hat,
                _block_correlation(
                    beta[: 1 if mu == 0 else None],
                    ph,
                    mu,
                    n_scans,
                    interval,
                    phi_deg,
                    model,
                    frozen_at_rest,
                ),
                n_lags,
            )
            for mu in REMOVED_D_MU
        ]
    )
    grid.flags.writeable = False  # shared by every caller through the cache
    return grid


def _grid_at(grid: np.ndarray, mu: np.ndarray, ratio: np.ndarray) -> np.ndarray:
    """``(cells, k, n_lags)``: ``grid`` (mu, x, lag) at ``mu`` and ``ratio`` ``(cells, k)``.

    ``mu`` ``(cells,)`` or ``(cells, k)``; linear in ``mu`` (clipped to the nodes), log-log
    in ``R'/L_V`` (clipped; linear in ``log(R'/L_V)`` where a node is not positive).
    """
    m = np.clip(np.nan_to_num(np.asarray(mu, float), nan=0.0), 0.0, REMOVED_D_MU[-1])
    m = np.broadcast_to(m if m.ndim == ratio.ndim else m[:, None], ratio.shape)
    j = np.clip(np.searchsorted(REMOVED_D_MU, m, side="right") - 1, 0, REMOVED_D_MU.size - 2)
    w = ((m - REMOVED_D_MU[j]) / (REMOVED_D_MU[j + 1] - REMOVED_D_MU[j]))[..., None]
    lx = np.log(REMOVED_D_X)
    pos = (np.log(np.clip(ratio, REMOVED_D_X[0], REMOVED_D_X[-1])) - lx[0]) / (lx[1] - lx[0])
    i0 = np.clip(np.floor(pos).astype(int), 0, lx.size - 2)  # (cells, k)
    frac = (pos - i0)[..., None]
    lo = (1.0 - w) * grid[j, i0] + w * grid[j + 1, i0]  # (cells, k, lag)
    hi = (1.0 - w) * grid[j, i0 + 1] + w * grid[j + 1, i0 + 1]
    positive = (lo > 0) & (hi > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_log = np.exp((1.0 - frac) * np.log(lo) + frac * np.log(hi))
    return np.where(positive, log_log, (1.0 - frac) * lo + frac * hi)


def _configurations(keys: np.ndarray) -> list[tuple[tuple, np.ndarray]]:
    """Distinct rows of ``keys (cells, n)`` with the cells of each."""
    uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
    return [
        (tuple(uniq[u].tolist()), np.nonzero(inverse.ravel() == u)[0]) for u in range(len(uniq))
    ]


def circle_removed_d(
    step_rad: np.ndarray,
    n_lags: int,
    ratio: np.ndarray,
    mu: np.ndarray,
    interval: np.ndarray,
    n_scans: np.ndarray,
    phi_deg: float,
    model: str,
    dense_reference: Callable[[int, tuple], np.ndarray] | None = None,
) -> np.ndarray:
    """``(cells, k, n_lags)``: share of sigma_V^2 the block-mean VAD wind takes from ``D(l)``
    of full-circle scans (``M = 2 pi / dtheta`` rays, e.g. 24- and 36-ray VADs).

    ``(2 C - Q)/sigma_V^2`` of :func:`sector_removed_d` for the rays of a circle (pairs
    within a scan, not wrapping from the last ray to the first), each at its own time,
    scans ``T_int`` apart; averaged over :data:`CIRCLE_DIRECTIONS` wind directions from
    the scan's first ray (the structure function holds no azimuth of a scan's start, and
    at 24 rays, ``mu`` 1, the removal varies by a few percent of itself over them).
    Tabulated once per ``(M, N, T_int/T_scan, phi, model)`` on :data:`REMOVED_D_MU` x
    :data:`REMOVED_D_X` and interpolated (:func:`_removed_d_grid`). Against the exact
    covariance of a 24-ray step-stare VAD (10 scans back to back, ``R'/L_V`` 0.71, ``mu``
    0) the block-mean fit removes 0.25/0.98/2.1 % of sigma_V^2 from D at lags 1-3.
    Dense circles (more than :data:`MAX_SECTOR_RAYS` rays) take that of the circle of
    :data:`MAX_SECTOR_RAYS` rays at their lag angles (:func:`_dense_circle`).

    Parameters
    ----------
    step_rad : numpy.ndarray
        ``(cells,)`` azimuth step ``dtheta`` (rad).
    n_lags : int
        Lags ``l = 1..n_lags``.
    ratio : numpy.ndarray
        ``(cells, k)`` values of ``R'/L_V``.
    mu : numpy.ndarray
        ``(cells,)`` or ``(cells, k)``: ``U/V_s`` of the transport (:func:`transport_mu`);
        at 0 the scans are independent, the no-transport limit of Smalikho (2020).
    interval, n_scans : numpy.ndarray
        ``(cells,)`` as :func:`sector_removed_share`.
    dense_reference : callable
        ``(ref_lags, setting) -> grid`` of the reference circle of dense circles
        (default :func:`dense_reference_grid`; the stages pass the table store's stored
        copy).
    """
    reference = dense_reference_grid if dense_reference is None else dense_reference
    out = np.zeros((*ratio.shape, n_lags))
    for rays, setting, at in _circles(step_rad, n_scans, interval, phi_deg, model):
        if rays > MAX_SECTOR_RAYS:
            out[at] = _dense_circle(rays, n_lags, setting, mu[at], ratio[at], reference)
            continue
        grid = _removed_d_grid(_circle_phase(rays), _CIRCLE_OFFSETS, n_lags, *setting, False)
        out[at] = _grid_at(grid, mu[at], ratio[at])
    return out


#: the wind directions (rad from a circle's first ray) the circles' removal averages over
_CIRCLE_OFFSETS = tuple(2.0 * np.pi * np.arange(CIRCLE_DIRECTIONS) / CIRCLE_DIRECTIONS)


def _circle_phase(rays: int) -> tuple[float, ...]:
    """Scan angles (rad from the first ray) of the ``rays`` rays of a full circle."""
    return tuple(2.0 * np.pi * np.arange(rays) / rays)


def _circles(
    step_rad: np.ndarray, n_scans: np.ndarray, interval: np.ndarray, phi_deg: float, model: str
) -> list[tuple[int, tuple, np.ndarray]]:
    """``(rays, setting, cells)`` of each distinct full circle of the cells (at least two
    rays, one scan): ``setting`` = scans, ``T_int/T_scan``, elevation and model."""
    n_rays = np.rint(2.0 * np.pi / np.asarray(step_rad, float))
    keys = np.stack([n_rays, np.rint(n_scans), np.round(interval, 2)], -1)
    return [
        (int(rays), (int(scans), float(inter), round(float(phi_deg), 2), model), at)
        for (rays, scans, inter), at in _configurations(keys)
        if rays >= 2 and scans >= 1
    ]


def circle_removed_variance(
    step_rad: np.ndarray,
    n_lags: int,
    ratio: np.ndarray,
    mu: np.ndarray,
    interval: np.ndarray,
    n_scans: np.ndarray,
    phi_deg: float,
    model: str,
) -> np.ndarray:
    """``(cells, k)``: share of sigma_V^2 the block-mean VAD wind takes from V'_L of a circle.

    ``tr(H rho)/M`` of the rays of a full circle of at most :data:`MAX_SECTOR_RAYS` rays,
    each at its own time, the scans ``T_int`` apart in the field the wind carries
    (:func:`_block_correlation`): scans carried less than ``L_V`` from one another are
    nearly the same field, and the block mean then takes up to N times the share of
    independent scans (:func:`share_on_curve` over N), which is its value at ``mu = 0``.
    NaN for denser circles. Arguments as :func:`circle_removed_d`, whose grid of ``n_lags``
    lags holds this share too (computed once for both).
    """
    out = np.full(ratio.shape, np.nan)
    for rays, setting, at in _circles(step_rad, n_scans, interval, phi_deg, model):
        if 3 <= rays <= MAX_SECTOR_RAYS:
            phase = _circle_phase(rays)
            grid = _removed_grids(phase, _CIRCLE_OFFSETS, int(n_lags), *setting, False)
            out[at] = _grid_at(grid[..., :1], mu[at], ratio[at])[..., 0]
    return out


def dense_grid_parameters(ref_lags: int, setting: tuple) -> dict:
    """The parameters that identify :func:`dense_reference_grid` (a cache key without the
    code version, which the table store adds)."""
    params = {"rays": MAX_SECTOR_RAYS, "lags": ref_lags, "setting": list(setting)}
    params |= {"directions": CIRCLE_DIRECTIONS}
    return params | {"mu": REMOVED_D_MU.tolist(), "x": REMOVED_D_X.tolist()}


def valid_dense_grid(grid: np.ndarray | None, ref_lags: int) -> bool:
    """Whether ``grid`` is a complete :func:`dense_reference_grid` of ``ref_lags`` lags."""
    shape = (REMOVED_D_MU.size, REMOVED_D_X.size, ref_lags)
    return grid is not None and grid.shape == shape and bool(np.isfinite(grid).all())


@functools.lru_cache(maxsize=64)
def dense_reference_grid(ref_lags: int, setting: tuple) -> np.ndarray:
    """:func:`_removed_d_grid` of the circle of :data:`MAX_SECTOR_RAYS` rays on
    :data:`REMOVED_D_MU` x :data:`REMOVED_D_X` x ``ref_lags`` lags: 3-6 s of correlations
    per ``(lags, N, T_int/T_scan, phi, model)``, kept in memory here and on disk by the
    table store (:func:`cwproc.tables.removed_share.stored_dense_grid`)."""
    phase = _circle_phase(MAX_SECTOR_RAYS)
    return _removed_d_grid(phase, _CIRCLE_OFFSETS, ref_lags, *setting, False)


#: fewest lags of the reference circle of :func:`_dense_circle` (6 deg steps: 60 deg,
#: the largest lag angle the structure function uses)
DENSE_REFERENCE_LAGS = 10


def _dense_circle(
    rays: int,
    n_lags: int,
    setting: tuple,
    mu: np.ndarray,
    ratio: np.ndarray,
    reference: Callable[[int, tuple], np.ndarray],
) -> np.ndarray:
    """``(cells, k, n_lags)``: the removal in D(l) of a circle of ``rays`` > 60 rays.

    The removal at lag angle ``alpha = l dtheta`` is of second order in ``alpha``:
    ``P_a - P_b`` of the fitted wind and the part of ``V_a - V_b`` correlated with it
    are both of first order. Its ratio to ``alpha^2`` varies little with the angle and
    converges with the rays (at ``R'/L_V`` 0.94, 30 deg: 9.66, 9.50, 9.39 x 1e-6 per
    deg^2 for 24, 36 and 72 rays at ``mu`` 0; 4.80, 4.49, 4.27 at ``mu`` 3), so the
    ratio of the circle of :data:`MAX_SECTOR_RAYS` rays, interpolated linearly in the
    angle (held below its first lag), times ``alpha^2`` stands for it: against the
    direct evaluation of 72 rays (lags 1-3, ``R'/L_V`` 0.94, 10 scans) within 0.2 % at
    ``mu`` 0 and 1 and 0.8 % at ``mu`` 3 (the removal is 0.1-0.4 % of D(l) there, and
    moves the free intercept by 4 % of ``2 sigma_e^2`` = 0.02 m2 s-2 at ``mu`` 1). The
    reference's grid holds :data:`DENSE_REFERENCE_LAGS` lags at least, so that scans of
    any density share it.
    ``setting``: scans per block, ``T_int/T_scan``, elevation (deg) and model;
    ``reference(ref_lags, setting)`` gives the reference circle's grid
    (:func:`dense_reference_grid` or a stored copy of it).
    """
    ref = MAX_SECTOR_RAYS
    angle = np.arange(1, n_lags + 1) * 2.0 * np.pi / rays
    needed = math.ceil(angle[-1] * ref / (2.0 * np.pi) - 1e-9) + 1
    ref_lags = min(max(needed, DENSE_REFERENCE_LAGS), ref // 2)  # one grid for most scans
    use = min(needed, ref_lags)  # >= 2; the cells interpolated at these lags only
    grid = reference(ref_lags, setting)[..., :use]
    ref_angle = np.arange(1, use + 1) * 2.0 * np.pi / ref
    per_angle2 = _grid_at(grid, mu, ratio) / ref_angle**2  # (cells, k, use)
    pos = np.interp(angle, ref_angle, np.arange(use, dtype=float))
    i0 = np.minimum(np.floor(pos).astype(int), use - 2)
    frac = pos - i0
    value = (1.0 - frac) * per_angle2[..., i0] + frac * per_angle2[..., i0 + 1]
    return value * angle**2


def _sector_rays(weights: np.ndarray, step_rad: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(rays, centre, start)`` per cell: the rays of a sector scan from its node weights.

    The pairs' node weights spread each lag-1 pair over two nodes ``Delta`` apart
    (variance ``Delta^2 / 6`` on average); a uniform sector of width ``W`` adds ``W^2 /
    12``: ``W`` and the centre (scan angle from the first node ``start``, rad) from the
    weighted mean and variance of the phase, then ``rays`` rays ``step_rad`` apart over
    ``W + step_rad``. The centre is rounded to 0.01 rad (0.6 deg), so that the sectors of
    a day fall into few configurations.
    """
    occupied = weights > 1e-12
    start = np.argmax(np.where(occupied, _empty_runs(occupied), -1), axis=-1)
    phase = _scan_start_phase(occupied)
    w = np.where(occupied, weights, 0.0)
    w = w / w.sum(-1, keepdims=True)
    centre = np.round(np.sum(w * phase, -1), 2)
    spread = np.sum(w * (phase - centre[:, None]) ** 2, -1) - (2.0 * np.pi / N_BINS) ** 2 / 6.0
    width = np.sqrt(12.0 * np.maximum(spread, 0.0))
    rays = np.maximum(np.rint(width / step_rad) + 1, 2)
    return rays, centre, start


def sector_removed_d(
    weights: np.ndarray,
    step_rad: np.ndarray,
    n_lags: int,
    ratio: np.ndarray,
    mu: np.ndarray,
    interval: np.ndarray,
    n_scans: np.ndarray,
    phi_deg: float,
    model: str,
) -> np.ndarray:
    """``(cells, k, n_lags)``: share of sigma_V^2 the block-mean VAD wind takes from ``D(l)``.

    The residuals of the block-mean fit (``V' = V - (1/N) sum_n H V^(n)``, ``H`` the VAD
    projection over the rays of a scan) have at a pair ``a, b`` of one scan ``E[(V'_a -
    V'_b)^2] = D_ab - 2 C + Q``, ``C = E[(V_a - V_b)(P_a - P_b)]``, ``Q = E[(P_a -
    P_b)^2]``; this is ``(2 C - Q) / sigma_V^2`` averaged over the pairs ``l`` rays
    apart. The rays are rebuilt ``dtheta`` apart over the sector the node weights span
    (:func:`_sector_rays`), so that each ray of a pair is also a point of the fit (its
    own share in the fitted wind is the larger part); point beams, seen at their own
    times in the field the wind carries, ``m U T_int`` further on between scans
    (Banakh et al. (1999), eqs. 15-16; Smalikho (2020), eq. 3; as
    :func:`sector_removed_share`); the wind direction from the cell's node weights.
    Tabulated once per configuration (rays, first node, scans, ``T_int/T_scan``) on
    :data:`REMOVED_D_MU` x :data:`REMOVED_D_X` and interpolated (:func:`_removed_d_grid`).
    Scans of more than :data:`MAX_SECTOR_RAYS` rays give 0 (180-ray circle with a 60 deg
    gap: about 1 % of D at lag 4).

    Parameters
    ----------
    weights : numpy.ndarray
        ``(cells, N_BINS)`` node weights of the pairs present (no NaN rows).
    step_rad : numpy.ndarray
        ``(cells,)`` azimuth step ``dtheta`` (rad).
    n_lags : int
        Lags ``l = 1..n_lags``.
    ratio : numpy.ndarray
        ``(cells, k)`` values of ``R'/L_V``.
    mu, interval, n_scans : numpy.ndarray
        ``(cells,)`` as :func:`sector_removed_share`.
    """
    th = azimuth_nodes()
    out = np.zeros((*ratio.shape, n_lags))
    rays, centre, start = _sector_rays(np.nan_to_num(weights), np.asarray(step_rad, float))
    keys = np.stack(
        [
            rays,
            centre,
            np.round(step_rad, 5),
            start,
            np.rint(n_scans),
            np.round(interval, 2),
        ],
        -1,
    )
    for (n_rays, mid, step, first, scans, inter), at in _configurations(keys):
        if n_rays > MAX_SECTOR_RAYS or scans < 1:
            continue  # a gappy circle: the fit's harmonics vary little over a pair
        phase = mid + step * (np.arange(int(n_rays)) - 0.5 * (n_rays - 1))
        grid = _removed_d_grid(
            tuple(phase.tolist()),
            (float(-th[int(first)]),),
            n_lags,
            int(scans),
            float(inter),
            round(float(phi_deg), 2),
            model,
            True,
        )
        out[at] = _grid_at(grid, mu[at], ratio[at])
    return out
