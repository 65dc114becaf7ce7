"""Share of sigma_V^2 the block-mean VAD wind removes from the radial-velocity deviations.

The deviations ``V'_L`` from the VAD fit (Smalikho (2020), eqs. 1-2) miss the part of
the variance the fitted wind takes: ``tr(H B)/M`` of the fit's hat matrix ``H`` and the
correlation tensor ``B`` of the isotropic field (Banakh et al. (1999), eqs. 15-16) at
the beams, seen at their own times in the field the wind carries (Smalikho (2020),
eq. 3). :func:`mean_removed_share` for full circles, :func:`sector_removed_share` for
sectors and gaps (:func:`partial_circle`). Pure numpy.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from cwproc.physics import spectra
from cwproc.physics.atable_interp import N_BINS, azimuth_nodes

#: nodes of mu = U/V_s of :func:`mean_removed_share` (linear interpolation between them)
REMOVED_SHARE_MU = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0])


#: wind directions (from the scan's first ray) averaged in :func:`mean_removed_share`
_REMOVED_SHARE_DIRECTIONS = 4


@functools.lru_cache(maxsize=16)
def _removed_share_curve(phi_deg: float, model: str) -> tuple[np.ndarray, np.ndarray]:
    """``(log x, r(mu, x))`` of :func:`mean_removed_share` on 25 nodes of ``x = R'/L_V``.

    ``tr(H B)/M`` of the VAD hat matrix ``H = (1 + 2 cos(theta_i - theta_j))/M`` of a
    full circle of 48 point beams and the correlation tensor ``B`` of the frozen field
    at the probes' positions in the field's frame, ``R' e(theta_m) - U t_m``: the rays
    follow each other over one scan period, so the wind carries the field ``mu R'
    theta_m`` along its direction (Smalikho (2020), eq. 3: ``U T = 2 pi mu R'``);
    averaged over :data:`_REMOVED_SHARE_DIRECTIONS` wind directions.
    """
    x = np.geomspace(1e-2, 1e2, 25)
    n_az = 48
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
            f, g = spectra.correlation_functions(r, model, 1.0)
            unit = np.where(r[..., None] > 0, r_vec / np.where(r > 0, r, 1.0)[..., None], 0.0)
            proj_i = np.einsum("xijk,ik->xij", unit, s)
            proj_j = np.einsum("xijk,jk->xij", unit, s)
            b = g * dot[None] + (f - g) * proj_i * proj_j
            share[i] += np.einsum("xij,ij->x", b, hat) / directions
    return np.log(x), share


def mean_removed_share(
    ratio: np.ndarray, phi_deg: float, model: str, mu: np.ndarray | float = 0.0
) -> np.ndarray:
    """Share of sigma_V^2 the scan-mean (VAD) wind takes from one scan's V'_L.

    ``tr(H B)/(M sigma_V^2)`` of a full circle of point beams, Banakh et al. (1999),
    eqs. 15-16 with the isotropic tensor of ``model``, the rays seen at their own times
    in the field carried by the wind (:func:`_removed_share_curve`); a function of
    ``ratio = R'/L_V`` and ``mu = U/V_s`` (tabulated once per elevation and model). The
    block mean of N independent scans removes this divided by N. The probe volume is
    neglected (the share is carried by scales of the circle, far above the probe).
    Transport matters: on exact 24-ray statistics at ``mu = 3`` (R'/L_V = 0.71) the
    block-mean wind removed 2.4 % of sigma_V^2, the frozen circle predicts 5.0 %; the
    overestimate biased the variance condition and eps 8 % low.
    """
    log_x, share = _removed_share_curve(round(float(phi_deg), 2), model)
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
def _correlation_curve(model: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    circle of independent scans gives :func:`mean_removed_share` over N. Exact
    statistics of a 90 deg sector scan (45 rays, 12 s apart): the fit removes 7.7 % of
    sigma_V^2 per scan, and, the scans being 1-2 L_V apart, 11-18 % of it in the block
    at mu 1-0.5 (the full circle: 4.6 %).

    Parameters
    ----------
    weights : numpy.ndarray
        ``(cells, N_BINS)`` node weights; rows that are NaN give NaN (the caller keeps
        :func:`mean_removed_share` there and for full circles, :func:`partial_circle`).
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
    log_r, f_c, g_c = _correlation_curve(model)
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


def _point_correlation(
    p: np.ndarray, q: np.ndarray, sp: np.ndarray, sq: np.ndarray, tables: tuple
) -> np.ndarray:
    """``(..., x)``: correlation of point beams ``sp`` at ``p`` and ``sq`` at ``q`` (R' units).

    Banakh et al. (1999), eqs. 15-16 with the isotropic tensor (``tables`` of
    :func:`_correlation_curve`) at ``r/L_V = |p - q| x`` for each ``x`` of
    :data:`_SECTOR_X`.
    """
    log_r, f_c, g_c = tables
    r_vec = p - q
    r = np.linalg.norm(r_vec, axis=-1)
    unit = r_vec / np.where(r > 0, r, 1.0)[..., None]
    proj = np.sum(unit * sp, -1) * np.sum(unit * sq, -1)
    dot = np.sum(sp * sq, -1)
    lr = np.log(np.maximum(r[..., None] * _SECTOR_X, 1e-5))
    f, g = np.interp(lr, log_r, f_c), np.interp(lr, log_r, g_c)
    return g * dot[..., None] + (f - g) * proj[..., None]


#: rays per scan beyond which :func:`sector_removed_d` leaves D(l) alone (its cost grows
#: as the square: 40 ms per cell at 46 rays, 0.5 s at 150; gaps of long continuous scans)
MAX_SECTOR_RAYS = 60


def _sector_rays(weights: np.ndarray, step_rad: float) -> np.ndarray:
    """Scan angles (rad, from the scan's first node) of the rays of a sector scan.

    The pairs' node weights spread each lag-1 pair over two nodes ``Delta`` apart
    (variance ``Delta^2 / 6`` on average); a uniform sector of width ``W`` adds ``W^2 /
    12``: ``W`` and the centre from the weighted mean and variance of the phase, then
    rays ``step_rad`` apart over ``W + step_rad``.
    """
    occupied = weights > 1e-12
    phase = _scan_start_phase(occupied[None])[0]
    w = np.where(occupied, weights, 0.0) / weights[occupied].sum()
    centre = float(np.sum(w * phase))
    spread = float(np.sum(w * (phase - centre) ** 2)) - (2.0 * np.pi / N_BINS) ** 2 / 6.0
    width = math.sqrt(12.0 * max(spread, 0.0))
    n_rays = max(round(width / step_rad) + 1, 2)
    return centre + step_rad * (np.arange(n_rays) - 0.5 * (n_rays - 1))


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
    :func:`sector_removed_share`). Scans of more than :data:`MAX_SECTOR_RAYS` rays
    give 0 (180-ray circle with a 60 deg gap: about 1 % of D at lag 4).

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
    tables = _correlation_curve(model)
    ph = math.radians(phi_deg)
    wind = np.array([1.0, 0.0, 0.0])
    th = azimuth_nodes()
    out = np.zeros((*ratio.shape, n_lags))
    for c in range(weights.shape[0]):
        w = np.nan_to_num(weights[c])
        phase = _sector_rays(w, float(step_rad[c]))
        start = int(np.argmax(np.where(w > 1e-12, _empty_runs((w > 1e-12)[None])[0], -1)))
        if phase.size > MAX_SECTOR_RAYS:
            continue  # a gappy circle: the fit's harmonics vary little over a pair
        beta = -th[start] + phase
        design = np.stack([np.ones(beta.size), np.cos(beta), np.sin(beta)], -1)
        hat = design @ np.linalg.pinv(design.T @ design) @ design.T  # (i, j)
        n = float(n_scans[c])
        m = np.arange(-int(n) + 1, int(n))
        mult = (n - np.abs(m)) / n**2
        shift = (mu[c] * 2.0 * np.pi * interval[c]) * m
        pos = np.stack([np.cos(beta), np.sin(beta), np.zeros(beta.size)], -1)
        pos = pos - (mu[c] * phase)[:, None] * wind
        beam = np.stack(
            [
                math.cos(ph) * np.cos(beta),
                math.cos(ph) * np.sin(beta),
                np.full(beta.size, math.sin(ph)),
            ],
            -1,
        )
        later = pos[None] - shift[:, None, None] * wind  # (m, j, 3): scan n + m
        # block-mean correlation of ray i (scan n) and ray j (scan n + m): (i, j, x)
        rho = np.einsum(
            "m,mijx->ijx",
            mult,
            _point_correlation(
                pos[None, :, None], later[:, None], beam[:, None], beam[None], tables
            ),
        )
        for li in range(min(n_lags, beta.size - 1)):
            lag = li + 1
            a, b = np.arange(beta.size - lag), np.arange(lag, beta.size)
            u = hat[a] - hat[b]  # (pairs, j): P_a - P_b per V_j
            cross = np.einsum("pj,pjx->px", u, rho[a] - rho[b])
            quad = np.einsum("pj,pk,jkx->px", u, u, rho)
            share = np.mean(2.0 * cross - quad, axis=0)
            query = np.clip(ratio[c], _SECTOR_X[0], _SECTOR_X[-1])
            out[c, :, li] = np.interp(np.log(query), np.log(_SECTOR_X), share)
    return out
