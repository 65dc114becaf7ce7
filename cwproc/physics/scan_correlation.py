"""How much the scans of a block are one sample: the errors of its means with correlated scans.

The standard errors of the block's statistics ``s = (D_L(1), ..., D_L(L), variance of
V'_L)`` come from the scatter of their per-scan values over the block's ``N`` scans
(the jackknife of :func:`cwproc.physics.block_stats.jackknife_covariance`), which counts
the scans as independent. Scans that see the same eddies are not: in the field the wind
carries (Taylor's hypothesis, Smalikho (2020), eq. 7) scan ``n + m`` sees the air the
scan ``n`` saw ``m U T_int`` upstream. A full circle at ``mu = U/V_s`` of 1 is carried
``2 pi R'`` per scan, three circle diameters; a sector scanned back to back is carried
only its own width, so its scans share their large eddies. The variance of a mean of
correlated samples is that of ``N_eff = N / (1 + 2 sum_k (1 - k/N) rho_k)`` independent
ones (Bayley and Hammersley (1946)), and the scatter about the block mean then
underestimates even the per-scan variance, by ``(N - N/N_eff) / (N - 1)``.

Both follow exactly from the covariance of the radial velocities, because every
statistic of the block is a quadratic form of a Gaussian vector: with ``V' = (I - P) V``
(``P`` the block-mean VAD fit, the same hat ``H`` of the scan's azimuths for every scan),
``s_n^a = V'_n^T K_a^T K_a V'_n`` (``K_a`` the ray differences ``l`` apart over the root
of their number for ``D_L(l)``, the identity over ``sqrt(M)`` for the variance) and the
covariance ``G`` of ``V'``,

.. math:: \\mathrm{cov}(s_n^a, s_{n'}^b) = 2 \\, \\| K_a G_{nn'} K_b^T \\|_F^2 .

:func:`correlation_inflation` compares the variance of the block mean with the
expectation of the scatter-based estimate, once with the scans' cross-covariance and
once with the scans independent (``G`` built with the cross-scan blocks of the
velocity covariance set to zero), and returns their ratio per statistic: the factor by
which the scatter-based variance of each block-mean statistic must grow. It is 1 where
the scans are independent, whatever the approximations of the model, which only enter
through the correlation between scans.

The velocity covariance is that of point beams in the frozen field (Banakh et al.
(1999), eqs. 15-16, the isotropic tensor of the model at ``r/L_V``) plus white noise of
``sigma_e^2`` on the diagonal: ray ``i`` of scan ``n`` at ``R' e(beta_i) - U t``, ``t``
its time (``R' theta / V_s`` within a scan from the scan's first ray, plus ``n T_int``),
as :mod:`cwproc.physics.removed_share` places them. Without transport (``U = 0``) the
field renews between scans (the no-transport limit of Smalikho (2020), also that of the
exact-statistics generator :mod:`cwproc.sim.exact_gaussian`); below
:data:`MU_FROZEN` the frozen correlation is weighted in linearly from that limit.

Reference: Bayley, G. V. and Hammersley, J. M. (1946), The "effective" number of
independent observations in an autocorrelated time series, J. R. Stat. Soc. Suppl. 8,
185-197 (``cwproc.references.BAYLEY_HAMMERSLEY_1946``).
"""

from __future__ import annotations

import math

import numpy as np

from cwproc.physics.removed_share import correlation_curve

#: ``mu = U/V_s`` from which the scans are the frozen field carried by the wind; below it
#: the frozen cross-scan correlation is scaled by ``mu / MU_FROZEN`` (at 0 the scans are
#: independent: the no-transport limit), as the removal of the block-mean wind from D
#: (:data:`cwproc.physics.removed_share.REMOVED_D_MU`, first node 0.05)
MU_FROZEN = 0.05

#: correlation model of the cross-scan covariance for spectrum models without one
#: (``inertial``: the von Karman field of the fitted L_V)
FALLBACK_MODEL = "von_karman"


def scan_positions(
    phase: np.ndarray, offset: float, mu: float, phi_deg: float
) -> tuple[np.ndarray, np.ndarray]:
    """Positions (units of ``R'``) in the frozen field and beam unit vectors of a scan's rays.

    Parameters
    ----------
    phase : numpy.ndarray
        ``(M,)`` scan angle of each ray from the scan's first ray (rad), in time order.
    offset : float
        Azimuth of the first ray from the direction the wind blows towards (rad).
    mu : float
        ``U/V_s`` (Smalikho (2020), eq. 3): the field moves ``mu R'`` per radian scanned.
    phi_deg : float
        Elevation (deg).

    Returns
    -------
    (pos, beam) : numpy.ndarray
        ``(M, 3)`` each; x along the wind.
    """
    beta = offset + np.asarray(phase, float)
    ph = math.radians(phi_deg)
    pos = np.stack([np.cos(beta), np.sin(beta), np.zeros(beta.shape)], -1)
    pos[:, 0] -= mu * np.asarray(phase, float)
    beam = np.stack(
        [
            math.cos(ph) * np.cos(beta),
            math.cos(ph) * np.sin(beta),
            np.full(beta.shape, math.sin(ph)),
        ],
        -1,
    )
    return pos, beam


def pair_geometry(
    pos: np.ndarray, beam: np.ndarray, shift: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Separations and beam projections of the ray pairs of scans ``m`` apart.

    The part of :func:`cross_scan_correlation` that does not depend on ``R'/L_V``: one
    geometry serves every node of ``R'/L_V``.

    Parameters
    ----------
    pos, beam : numpy.ndarray
        ``(..., M, 3)`` of :func:`scan_positions` (any leading axes: start angles).
    shift : numpy.ndarray
        ``(m,)`` transport between the scans (units of ``R'``).

    Returns
    -------
    (r, dot, proj) : numpy.ndarray
        ``(..., m, M, M)`` distance ``|p_i - p_j + shift_m e_x|`` (units of ``R'``),
        ``(..., 1, M, M)`` ``s_i.s_j`` and ``(..., m, M, M)`` ``(s_i.e)(s_j.e)``
        (Banakh et al. (1999), eq. 16).
    """
    r_vec = pos[..., None, :, None, :] - pos[..., None, None, :, :]
    r_vec = r_vec + np.asarray(shift, float)[:, None, None, None] * np.array([1.0, 0.0, 0.0])
    r = np.linalg.norm(r_vec, axis=-1)
    unit = r_vec / np.where(r > 0, r, 1.0)[..., None]
    beam_i, beam_j = beam[..., None, :, None, :], beam[..., None, None, :, :]
    proj = np.sum(unit * beam_i, axis=-1) * np.sum(unit * beam_j, axis=-1)
    dot = (beam @ np.swapaxes(beam, -1, -2))[..., None, :, :]
    return r, dot, proj


def correlation_at(
    geometry: tuple[np.ndarray, np.ndarray, np.ndarray], ratio: np.ndarray, model: str
) -> np.ndarray:
    """``(X, ..., m, M, M)``: :func:`cross_scan_correlation` at each ``R'/L_V`` of ``ratio``.

    ``g(r) s_i.s_j + [f(r) - g(r)] (s_i.e)(s_j.e)`` (Banakh et al. (1999), eq. 16), ``f,
    g`` of ``model`` by interpolation in ``ln r`` at ``r`` in units of ``L_V``.

    Parameters
    ----------
    geometry : tuple of numpy.ndarray
        ``(r, dot, proj)`` of :func:`pair_geometry`.
    ratio : numpy.ndarray
        ``(X,)`` ``R'/L_V``.
    model : str
        ``"von_karman"`` or ``"exponential"``.
    """
    r, dot, proj = geometry
    log_r, f_c, g_c = correlation_curve(model)
    scale = np.asarray(ratio, float).reshape((-1,) + (1,) * r.ndim)
    with np.errstate(divide="ignore"):
        lr = np.log(np.maximum(r * scale, 1e-300))
    f = np.interp(lr, log_r, f_c, left=1.0)
    g = np.interp(lr, log_r, g_c, left=1.0)
    return g * dot + (f - g) * proj


def cross_scan_correlation(
    pos: np.ndarray,
    beam: np.ndarray,
    shift: np.ndarray,
    ratio: float,
    model: str,
) -> np.ndarray:
    """``(m, M, M)``: correlation (over ``sigma_V^2``) of ray ``i`` of scan ``n + m`` and ray
    ``j`` of scan ``n``.

    ``g(r) s_i.s_j + [f(r) - g(r)] (s_i.e)(s_j.e)`` (Banakh et al. (1999), eq. 16) at
    ``r = |p_i - p_j + shift_m e_x| ratio`` in units of ``L_V`` (``ratio = R'/L_V``),
    ``f, g`` of ``model`` by interpolation in ``ln r`` (:func:`pair_geometry`,
    :func:`correlation_at`).

    Parameters
    ----------
    pos, beam : numpy.ndarray
        ``(M, 3)`` of :func:`scan_positions`.
    shift : numpy.ndarray
        ``(m,)`` transport between the scans (units of ``R'``).
    ratio : float
        ``R'/L_V``.
    model : str
        ``"von_karman"`` or ``"exponential"``.
    """
    return correlation_at(pair_geometry(pos, beam, shift), np.array([ratio]), model)[0]


def _vad_hat(phase: np.ndarray, offset: float) -> np.ndarray:
    """``(M, M)`` hat matrix of the least-squares VAD fit ``(1, cos beta, sin beta)``."""
    beta = offset + np.asarray(phase, float)
    design = np.stack([np.ones(beta.size), np.cos(beta), np.sin(beta)], -1)
    return design @ np.linalg.pinv(design.T @ design) @ design.T


def _residual_covariance(blocks: np.ndarray, hat: np.ndarray) -> np.ndarray:
    """``(N, N, M, M)`` covariance of ``V' = (I - J x H) V`` from that of ``V`` (same shape).

    ``J = 1 1^T / N``: the block-mean VAD wind is the mean of the scans' fits (the same
    azimuths in every scan).
    """
    row_mean = blocks.mean(axis=0)  # (N', M, M): (1/N) sum_n G_{n n'}
    col_mean = blocks.mean(axis=1)  # (N, M, M): (1/N) sum_n' G_{n n'}
    all_mean = row_mean.mean(axis=0)  # (M, M)
    left = np.einsum("ij,njk->nik", hat, row_mean)  # H (1/N sum_n G_{n n'}) -> rows any n
    right = np.einsum("nij,kj->nik", col_mean, hat)  # (1/N sum_n' G_{n n'}) H^T
    both = hat @ all_mean @ hat.T
    return blocks - left[None, :, :, :] - right[:, None, :, :] + both[None, None]


def _difference_rows(g: np.ndarray, lag: int) -> np.ndarray:
    """``K_a g`` over the second-to-last axis: differences ``lag`` apart over the root of
    their number, or the identity over ``sqrt(M)`` for ``lag`` 0."""
    m = g.shape[-2]
    if lag == 0:
        return g / math.sqrt(m)
    return (g[..., lag:, :] - g[..., :-lag, :]) / math.sqrt(m - lag)


def statistic_terms(residual: np.ndarray, n_lags: int) -> np.ndarray:
    """``(L + 1, L + 1, N, N)``: ``||K_a G_{nn'} K_b^T||_F^2`` for the lags 1..L and the variance.

    Half the covariance of the per-scan statistics ``a`` of scan ``n`` and ``b`` of
    scan ``n'`` (module doc).
    """
    lags = [*range(1, n_lags + 1), 0]
    n = residual.shape[0]
    out = np.empty((len(lags), len(lags), n, n))
    rows = [_difference_rows(residual, lag) for lag in lags]
    for a, ra in enumerate(rows):
        ra_t = np.swapaxes(ra, -1, -2)
        for b in range(a, len(lags)):
            both = _difference_rows(ra_t, lags[b])  # (K_b (K_a G)^T) = (K_a G K_b^T)^T
            out[a, b] = out[b, a] = np.einsum("nkij,nkij->nk", both, both)
    return out


def statistic_means(residual: np.ndarray, n_lags: int) -> np.ndarray:
    """``(L + 1, N)`` expectations ``tr(K_a G_nn K_a^T)`` of the per-scan statistics."""
    lags = [*range(1, n_lags + 1), 0]
    idx = np.arange(residual.shape[0])
    own = residual[idx, idx]  # (N, M, M)
    out = np.empty((len(lags), idx.size))
    for a, lag in enumerate(lags):
        both = _difference_rows(np.swapaxes(_difference_rows(own, lag), -1, -2), lag)
        out[a] = np.trace(both, axis1=-2, axis2=-1)
    return out


def _mean_and_scatter(terms: np.ndarray, means: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Diagonals of the variance of the block means and of the expected scatter estimate.

    ``var(s_mean) = (2/N^2) sum_{n n'} T``; the scatter ``sum_n (s_n - s_mean)^2 / (N (N -
    1))`` has the expectation ``[(2/N) sum_n T_nn + (1/N) sum_n (E s_n - E s_mean)^2 -
    var(s_mean)] / (N - 1)`` (``means``: the ``E s_n``, which the block-mean wind makes
    differ a little between the first, middle and last scans).
    """
    diag = np.einsum("aann->an", terms)  # (L + 1, N)
    n = terms.shape[-1]
    total = 2.0 * np.einsum("aank->a", terms) / n**2
    spread = np.mean((means - means.mean(-1, keepdims=True)) ** 2, axis=-1)
    scatter = (2.0 * diag.sum(-1) / n + spread - total) / (n - 1)
    return total, scatter


def correlation_inflation(
    phase: np.ndarray,
    offset: float,
    mu: float,
    interval: float,
    n_scans: int,
    ratio: float,
    noise_ratio: float,
    n_lags: int,
    phi_deg: float,
    model: str,
) -> np.ndarray:
    """``(L + 1,)`` factor of the scatter-based variance of ``D_L(1..L)`` and the variance.

    The variance of each block-mean statistic over the expectation of its estimate from
    the scatter of the scans (the jackknife), with the scans' correlation in the frozen
    field, relative to the same ratio for independent scans (module doc): 1 for
    independent scans, larger where the scans see the same eddies.

    Parameters
    ----------
    phase : numpy.ndarray
        ``(M,)`` scan angle of each ray from the first (rad), in time order.
    offset : float
        Azimuth of the first ray from the direction the wind blows towards (rad).
    mu : float
        ``U/V_s`` of the transport (Smalikho (2020), eq. 3).
    interval : float
        Time between scan starts over ``T_scan`` (``2 pi R'/V_s``).
    n_scans : int
        Scans per block N (>= 2).
    ratio : float
        ``R'/L_V``.
    noise_ratio : float
        ``sigma_e^2 / sigma_V^2``.
    n_lags : int
        Lags ``l = 1..L``.
    phi_deg : float
        Elevation (deg).
    model : str
        Correlation model (:data:`FALLBACK_MODEL` for one without a correlation).
    """
    out = np.ones(n_lags + 1)
    if n_scans < 2 or not (math.isfinite(mu) and math.isfinite(ratio) and ratio > 0):
        return out
    model = model if model in ("von_karman", "exponential") else FALLBACK_MODEL
    frozen = min(max(mu, 0.0), 1e6)
    weight = min(frozen / MU_FROZEN, 1.0)
    if weight <= 0.0:
        return out
    mu_c = max(frozen, MU_FROZEN)
    pos, beam = scan_positions(phase, offset, mu_c, phi_deg)
    shift = -mu_c * 2.0 * math.pi * interval * np.arange(n_scans)
    rho = cross_scan_correlation(pos, beam, shift, ratio, model)  # (m, M, M)
    m_rays = pos.shape[0]
    blocks = np.zeros((n_scans, n_scans, m_rays, m_rays))
    noise = max(float(noise_ratio), 0.0) * np.eye(m_rays)
    for n in range(n_scans):
        for k in range(n, n_scans):
            blocks[n, k] = weight * rho[k - n].T if k > n else rho[0] + noise
            blocks[k, n] = blocks[n, k].T
    independent = np.zeros_like(blocks)
    idx = np.arange(n_scans)
    independent[idx, idx] = blocks[idx, idx]
    hat = _vad_hat(phase, offset)
    ratios = []
    for cov in (blocks, independent):
        residual = _residual_covariance(cov, hat)
        total, scatter = _mean_and_scatter(
            statistic_terms(residual, n_lags), statistic_means(residual, n_lags)
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            ratios.append(total / scatter)
    with np.errstate(invalid="ignore", divide="ignore"):
        factor = ratios[0] / ratios[1]
    return np.where(np.isfinite(factor) & (factor > 0), factor, 1.0)


def _scan_blocks(
    phase: np.ndarray,
    offset: float,
    mu: float,
    interval: float,
    n_scans: int,
    ratio: float,
    noise_ratio: float,
    phi_deg: float,
    model: str,
) -> tuple[np.ndarray, np.ndarray]:
    """``(N, N, M, M)`` velocity covariances (over sigma_V^2) of a block's scans: with their
    correlation in the frozen field (weighted in up to :data:`MU_FROZEN`), and the same
    with the scans independent (the cross-scan blocks zero). Module doc. The direct
    construction, the reference of :func:`refit_jackknife_factors` (which forms only the
    ``2 N - 1`` distinct blocks; tests)."""
    weight = min(max(mu, 0.0) / MU_FROZEN, 1.0)
    mu_c = max(min(max(mu, 0.0), 1e6), MU_FROZEN)
    pos, beam = scan_positions(phase, offset, mu_c, phi_deg)
    shift = -mu_c * 2.0 * math.pi * interval * np.arange(n_scans)
    rho = cross_scan_correlation(pos, beam, shift, ratio, model)  # (m, M, M)
    m_rays = pos.shape[0]
    blocks = np.zeros((n_scans, n_scans, m_rays, m_rays))
    own = rho[0] + max(float(noise_ratio), 0.0) * np.eye(m_rays)
    for n in range(n_scans):
        blocks[n, n] = own
        for k in range(n + 1, n_scans):
            blocks[n, k] = weight * rho[k - n].T
            blocks[k, n] = blocks[n, k].T
    independent = np.zeros_like(blocks)
    idx = np.arange(n_scans)
    independent[idx, idx] = own
    return blocks, independent


def refit_variance_moments(blocks: np.ndarray, design: np.ndarray) -> tuple[float, float]:
    """Variance of the block's variance statistic and the expectation of its refit jackknife.

    The statistic is ``s = (1/N) sum_n |V'_n|^2 / M``, ``V'_n = V_n - H <V>`` (the
    block-mean VAD fit, ``H`` the hat of ``design``); the jackknife of
    :func:`cwproc.physics.block_stats.jackknife_covariance` recomputes it without scan
    ``k`` with the wind refitted without it, ``theta_k``, and reports ``(N - 1)/N sum_k
    (theta_k - <theta>)^2``. With ``Q`` an orthonormal basis of the fit's columns,
    ``r_n = (I - Q Q^T) V_n`` and ``c_n = Q^T V_n``, ``|V_n - H w|^2 = |r_n|^2 + |c_n -
    w|^2``: every ``theta_k`` is ``sum_n alpha_kn a_n + c^T (gamma_k x I_3) c / M`` with
    ``a_n = |r_n|^2 / M``, so its moments follow from the Gaussian fourth moments
    ``cov(x^T A x, x^T B x) = 2 tr(A G B G)`` over blocks of at most ``M x M``
    (:func:`_jackknife_moments`).

    Parameters
    ----------
    blocks : numpy.ndarray
        ``(N, N, M, M)`` covariance of the rays of the block's scans (any unit ``u``).
    design : numpy.ndarray
        ``(M, p)`` the VAD fit's columns at the scan's rays.

    Returns
    -------
    (variance, jackknife) : float
        ``var(s)`` and ``E[jackknife estimate of var(s)]`` (``u^2``).
    """
    m_rays = blocks.shape[2]
    q_basis = np.linalg.qr(design)[0]  # (M, p)
    proj = np.eye(m_rays) - q_basis @ q_basis.T
    g_rr = proj @ blocks @ proj  # (N, N, M, M)
    g_rc = proj @ blocks @ q_basis  # (N, N, M, p)
    g_cc = q_basis.T @ blocks @ q_basis  # (N, N, p, p)
    mean_a = np.trace(np.diagonal(g_rr, axis1=0, axis2=1), axis1=0, axis2=1) / m_rays
    cov_a = 2.0 * np.einsum("nmij,nmij->nm", g_rr, g_rr) / m_rays**2
    variance, jack = _jackknife_moments(mean_a, cov_a, g_rc, g_cc, m_rays)
    return float(variance), float(jack)


def _jackknife_moments(
    mean_a: np.ndarray, cov_a: np.ndarray, g_rc: np.ndarray, g_cc: np.ndarray, m_rays: int
) -> tuple[np.ndarray, np.ndarray]:
    """``var(s)`` and the expectation of its refit jackknife (:func:`refit_variance_moments`).

    Parameters
    ----------
    mean_a : numpy.ndarray
        ``(..., N)`` ``E a_n`` (``a_n = |r_n|^2 / M``).
    cov_a : numpy.ndarray
        ``(..., N, N)`` ``cov(a_n, a_m) = 2 ||G^rr_nm||_F^2 / M^2``.
    g_rc, g_cc : numpy.ndarray
        ``(..., N, N, M, p)`` ``(I - Q Q^T) G_nm Q`` and ``(..., N, N, p, p)`` ``Q^T G_nm Q``.
    m_rays : int
        Rays per scan ``M``.

    Returns
    -------
    (variance, jackknife) : numpy.ndarray
        ``(...)`` each.
    """
    n = mean_a.shape[-1]
    lead = mean_a.shape[:-1]
    rc = g_rc.reshape((*lead, n, n, -1))
    w = (rc @ np.swapaxes(rc, -1, -2)).reshape((*lead, n, n * n))  # tr(G^rc_np G^rc_nq^T)
    trace_cc = np.trace(g_cc, axis1=-2, axis2=-1)  # (..., a, b): tr_p of the block (a, b)
    # tr(G_bc G_da) over the fit's columns, as a matrix over (a b) x (c d)
    four = g_cc.reshape((*lead, n * n, -1)) @ np.swapaxes(g_cc, -1, -2).reshape(
        (*lead, n * n, -1)
    ).swapaxes(-1, -2)
    four = np.moveaxis(four.reshape((*lead, n, n, n, n)), -1, -4).reshape((*lead, n * n, n * n))
    trace_ba = np.swapaxes(trace_cc, -1, -2).reshape((*lead, n * n))

    def moments(alpha: np.ndarray, gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Means and variances of ``alpha_k . a + c^T (gamma_k x I) c / M`` (``k``: rows)."""
        flat = gamma.reshape(gamma.shape[0], n * n)
        mean = mean_a @ alpha.T + trace_ba @ flat.T / m_rays
        var = np.sum((alpha @ cov_a) * alpha, axis=-1)
        var += 2.0 * np.sum((flat @ four) * flat, axis=-1) / m_rays**2
        var += 4.0 * np.sum(alpha.T * (w @ flat.T), axis=-2) / m_rays**2
        return mean, var

    centre = np.eye(n) - 1.0 / n
    variance = moments(np.full((1, n), 1.0 / n), centre[None] / n)[1][..., 0]
    keep = 1.0 - np.eye(n)  # (k, n): the scans of leave-one-out k
    alphas = keep / (n - 1.0)
    gammas = (keep[:, :, None] * np.eye(n) - keep[:, :, None] * keep[:, None, :] / (n - 1.0)) / (
        n - 1.0
    )
    mean, var = moments(alphas - alphas.mean(0), gammas - gammas.mean(0))
    jack = np.sum(var + mean**2, axis=-1)
    return variance, jack * (n - 1.0) / n


#: nodes of ``R'/L_V`` of :func:`circle_variance_factor` (log-linear interpolation,
#: clipped): the factor is smooth in ``log(R'/L_V)`` and 1 beyond the last
FACTOR_X = np.geomspace(0.03, 30.0, 7)

#: nodes of the angle of a block's first ray from the wind's direction of motion (deg,
#: periodic linear interpolation): at ``mu = 1`` the factor of a 24-ray VAD varies from
#: 1.02 to 1.2 over the start angle, with one peak about 60 deg wide
FACTOR_ANGLES = np.arange(0.0, 360.0, 30.0)

#: nodes of ``mu`` (linear interpolation, clipped): those of the removal in D(l)
FACTOR_MU = np.array([0.0, 0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0, 1.4, 2.0, 3.0, 5.0, 10.0])


def circle_factor_slice(
    n_rays: int, n_scans: int, interval: float, phi_deg: float, model: str, mu: float
) -> np.ndarray:
    """``(x, angle)``: :func:`refit_jackknife_factor` of a circle of ``n_rays`` rays (first
    ray at scan angle 0, ``n_scans`` scans ``interval`` scan periods apart) at ``mu``, on
    :data:`FACTOR_X` x :data:`FACTOR_ANGLES` (:func:`refit_jackknife_factors`: about 0.07 s
    of one core for 24 rays and 10 scans, 0.2 s for 36; 1 s and 1.9 s cell by cell)."""
    if mu <= 0.0 or n_scans < 2:
        return np.ones((FACTOR_X.size, FACTOR_ANGLES.size))
    phase = 2.0 * np.pi * np.arange(n_rays) / n_rays
    offsets = np.radians(FACTOR_ANGLES)
    return refit_jackknife_factors(
        phase, offsets, mu, interval, n_scans, FACTOR_X, 0.0, phi_deg, model
    )


def refit_jackknife_factor(
    phase: np.ndarray,
    offset: float,
    mu: float,
    interval: float,
    n_scans: int,
    ratio: float,
    noise_ratio: float,
    phi_deg: float,
    model: str,
) -> float:
    """Factor of the refit jackknife's variance of the block's variance statistic.

    ``[var(s) / E J]`` with the scans correlated in the frozen field over the same ratio
    with the scans independent (:func:`refit_variance_moments`): 1 for independent scans
    whatever the approximations of the velocity covariance (point beams), larger where
    consecutive scans see the same eddies. Parameters as :func:`correlation_inflation`;
    computed by :func:`refit_jackknife_factors`.
    """
    if n_scans < 2 or not (math.isfinite(mu) and math.isfinite(ratio) and ratio > 0):
        return 1.0
    factors = refit_jackknife_factors(
        phase,
        np.array([offset]),
        mu,
        interval,
        n_scans,
        np.array([ratio]),
        noise_ratio,
        phi_deg,
        model,
    )
    return float(factors[0, 0])


#: elements of the largest ``(R'/L_V, angle, distinct block, M, M)`` array
#: :func:`refit_jackknife_factors` builds at once (the start angles are taken in chunks)
CHUNK_ELEMENTS = 2_000_000


def refit_jackknife_factors(
    phase: np.ndarray,
    offsets: np.ndarray,
    mu: float,
    interval: float,
    n_scans: int,
    ratios: np.ndarray,
    noise_ratio: float,
    phi_deg: float,
    model: str,
) -> np.ndarray:
    """``(X, A)``: :func:`refit_jackknife_factor` at each ``R'/L_V`` and start angle.

    The same numbers as :func:`_scan_blocks` and :func:`refit_variance_moments` cell by
    cell (to rounding), reformulated: the velocity covariance of the block is block
    Toeplitz, ``G_{n+d, n} = w rho_d`` and ``G_{n, n+d} = w rho_d^T`` (``w`` the weight
    of :data:`MU_FROZEN`), so the projections ``P G_nm P``, ``P G_nm Q`` and ``Q^T G_nm
    Q`` of the moments are formed once per distinct block (``2 N - 1`` of them instead of
    ``N^2``), those of the independent scans are the diagonal ones (``w = 0``), the
    separations of the rays (:func:`pair_geometry`) serve every ``R'/L_V``, and every
    angle and ``R'/L_V`` go through the moments (:func:`_jackknife_moments`) together.

    Parameters
    ----------
    phase : numpy.ndarray
        ``(M,)`` scan angle of each ray from the first (rad), in time order.
    offsets : numpy.ndarray
        ``(A,)`` azimuths of the first ray from the direction the wind blows towards (rad).
    mu, interval, n_scans, noise_ratio, phi_deg, model
        As :func:`correlation_inflation`.
    ratios : numpy.ndarray
        ``(X,)`` ``R'/L_V``.
    """
    offsets = np.atleast_1d(np.asarray(offsets, float))
    ratios = np.atleast_1d(np.asarray(ratios, float))
    out = np.ones((ratios.size, offsets.size))
    good = np.isfinite(ratios) & (ratios > 0)
    if n_scans < 2 or not math.isfinite(mu) or mu <= 0.0 or not good.any():
        return out
    model = model if model in ("von_karman", "exponential") else FALLBACK_MODEL
    phase = np.asarray(phase, float)
    per_angle = int(good.sum()) * (2 * n_scans - 1) * phase.size**2
    step = max(1, CHUNK_ELEMENTS // per_angle)
    settings = (mu, interval, n_scans, noise_ratio, phi_deg, model)
    for a0 in range(0, offsets.size, step):
        chunk = offsets[a0 : a0 + step]
        out[good, a0 : a0 + chunk.size] = _factor_chunk(phase, chunk, ratios[good], *settings)
    return out


def _factor_chunk(
    phase: np.ndarray,
    offsets: np.ndarray,
    ratios: np.ndarray,
    mu: float,
    interval: float,
    n_scans: int,
    noise_ratio: float,
    phi_deg: float,
    model: str,
) -> np.ndarray:
    """``(X, A)`` of :func:`refit_jackknife_factors` for finite ``mu > 0`` and ``ratios > 0``."""
    weight = min(max(mu, 0.0) / MU_FROZEN, 1.0)
    mu_c = max(min(max(mu, 0.0), 1e6), MU_FROZEN)
    placed = [scan_positions(phase, float(offset), mu_c, phi_deg) for offset in offsets]
    pos, beam = (np.stack(part) for part in zip(*placed, strict=True))  # (A, M, 3)
    shift = -mu_c * 2.0 * math.pi * interval * np.arange(n_scans)
    rho = correlation_at(pair_geometry(pos, beam, shift), ratios, model)  # (X, A, N, M, M)
    m_rays = phase.size
    own = rho[..., :1, :, :] + max(float(noise_ratio), 0.0) * np.eye(m_rays)
    lower = weight * rho[..., 1:, :, :]  # G_{n+d, n}; its transpose is G_{n, n+d}
    distinct = np.concatenate([own, lower, np.swapaxes(lower, -1, -2)], axis=-3)
    beta = offsets[:, None] + phase
    design = np.stack([np.ones(beta.shape), np.cos(beta), np.sin(beta)], -1)  # (A, M, 3)
    q_basis = np.linalg.qr(design)[0][:, None]  # (A, 1, M, p)
    q_t = np.swapaxes(q_basis, -1, -2)
    proj = np.eye(m_rays) - q_basis @ q_t
    left = proj @ distinct
    g_rr = left @ proj  # (X, A, K, M, M)
    g_rc = left @ q_basis
    g_cc = q_t @ distinct @ q_basis
    norm2 = np.einsum("...kij,...kij->...k", g_rr, g_rr)
    mean_a = np.trace(g_rr[..., 0, :, :], axis1=-2, axis2=-1) / m_rays  # (X, A)
    scans = np.arange(n_scans)
    gap = scans[:, None] - scans[None, :]
    index = np.where(gap > 0, gap, np.where(gap < 0, n_scans - 1 - gap, 0))  # (N, N)
    same = (index == 0)[..., None, None]
    cov_a = 2.0 * norm2[..., index] / m_rays**2
    g_rc, g_cc = g_rc[..., index, :, :], g_cc[..., index, :, :]
    stacked = (
        np.stack([cov_a, np.where(index == 0, cov_a, 0.0)]),
        np.stack([g_rc, np.where(same, g_rc, 0.0)]),
        np.stack([g_cc, np.where(same, g_cc, 0.0)]),
    )
    mean_n = np.broadcast_to(mean_a[..., None], (2, *mean_a.shape, n_scans))
    variance, jack = _jackknife_moments(mean_n, *stacked, m_rays)
    with np.errstate(invalid="ignore", divide="ignore"):
        factor = (variance[0] / jack[0]) / (variance[1] / jack[1])
    return np.where(np.isfinite(factor) & (factor > 0), factor, 1.0)
