"""Correlation of the radial velocity of isotropic turbulence seen by a lidar probe.

The longitudinal correlation models (Banakh et al. (1999), eq. 17, and von Karman),
the isotropic solenoidal correlation tensor (eq. 16), its projection on two beams
averaged over their probe volumes (eqs. 15-16, 20-21), and the azimuth correlation of
a conical scan with transport of the frozen field by the mean wind. The retrieval
(exact lag models of the structure function) and the virtual instrument (Cholesky
factors of these matrices) both use them.

Coordinates are (z, x, y) = (up, north, east); the beam unit vector is
S(theta) = (sin phi, cos phi cos theta, cos phi sin theta) with theta the azimuth
clockwise from north and phi the elevation (Banakh et al. (1999), eq. 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from cwproc.physics.geometry import beam_unit_vector_une, wind_components
from cwproc.physics.spectra import EXPONENTIAL_COEFFICIENT, correlation_functions

CorrelationModel = Literal["exponential", "von_karman"]


def longitudinal_correlation(
    r: np.ndarray, sigma2: float, outer_scale: float, model: CorrelationModel = "exponential"
) -> np.ndarray:
    """B_V(r) = sigma_V^2 f(r) (m2 s-2): Banakh et al. (1999), eq. 17, or von Karman.

    Parameters
    ----------
    r : numpy.ndarray
        Separation (m).
    sigma2 : float
        Velocity variance sigma_V^2 (m2 s-2).
    outer_scale : float
        Integral scale L_V (m).
    model : {"exponential", "von_karman"}
        ``f`` of :func:`cwproc.physics.spectra.correlation_functions`.
    """
    f, _ = correlation_functions(np.abs(np.asarray(r, dtype=float)), model, outer_scale)
    return sigma2 * f


def _correlation_pair(
    r: np.ndarray, sigma2: float, outer_scale: float, model: CorrelationModel
) -> tuple[np.ndarray, np.ndarray]:
    """sigma^2 g(r) and sigma^2 [g(r) - f(r)] = (r/2) dB_V/dr (m2 s-2), eq. 16."""
    f, g = correlation_functions(r, model, outer_scale)
    return sigma2 * g, sigma2 * (g - f)


def correlation_tensor(
    r_vec: np.ndarray, sigma2: float, outer_scale: float, model: CorrelationModel = "exponential"
) -> np.ndarray:
    """Isotropic solenoidal correlation tensor B_ik(r), Banakh et al. (1999), eq. 16.

    B_ik(r) = sigma^2 [g(r) delta_ik - (g(r) - f(r)) r_i r_k / r^2], i.e.
    B_V delta_ik + (r/2) dB_V/dr (delta_ik - r_i r_k / r^2).

    Parameters
    ----------
    r_vec : numpy.ndarray
        Separation vectors, shape (..., 3) (m).
    sigma2, outer_scale : float
        sigma_V^2 (m2 s-2) and L_V (m).
    model : {"exponential", "von_karman"}

    Returns
    -------
    numpy.ndarray
        Shape (..., 3, 3) (m2 s-2).
    """
    r_vec = np.asarray(r_vec, dtype=float)
    r = np.linalg.norm(r_vec, axis=-1)
    transverse, rb = _correlation_pair(r, sigma2, outer_scale, model)
    unit = np.where(r[..., None] > 0, r_vec / np.where(r > 0, r, 1.0)[..., None], 0.0)
    eye = np.eye(3)
    return transverse[..., None, None] * eye - rb[..., None, None] * (
        unit[..., :, None] * unit[..., None, :]
    )


def projected_correlation(
    r_vec: np.ndarray,
    s1: np.ndarray,
    s2: np.ndarray,
    sigma2: float,
    outer_scale: float,
    model: CorrelationModel = "exponential",
) -> np.ndarray:
    """sum_ik S1_i S2_k B_ik(r): correlation of the projections S1.V(r1), S2.V(r2).

    The integrand of Banakh et al. (1999), eq. 15, with B_ik of eq. 16 contracted
    without forming the tensor: B (S1.S2) + (r/2) B' [S1.S2 - (S1.r)(S2.r)/r^2].

    Parameters
    ----------
    r_vec : numpy.ndarray
        Separations r1 - r2, shape (..., 3) (m).
    s1, s2 : numpy.ndarray
        Unit beam vectors, broadcastable to (..., 3).

    Returns
    -------
    numpy.ndarray
        Shape (...) (m2 s-2).
    """
    r = np.sqrt(np.sum(r_vec * r_vec, axis=-1))
    dot = np.sum(s1 * s2, axis=-1)
    safe = np.where(r > 0, r, 1.0)
    p1 = np.sum(s1 * r_vec, axis=-1) / safe
    p2 = np.sum(s2 * r_vec, axis=-1) / safe
    transverse, rb = _correlation_pair(r, sigma2, outer_scale, model)
    return transverse * dot - rb * p1 * p2


# --------------------------------------------------------------------------------------
# probe volume and scan geometry
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ProbeQuadrature:
    """Nodes and weights of the probe-volume weighting along the beam.

    ``sum(weights) == 1``; the volume-averaged radial velocity is
    V_D = sum_j weights_j V_r(nodes_j) (Banakh et al. (1999), eq. 12).

    Attributes
    ----------
    nodes : tuple of float
        Distances from the lidar along the beam (m).
    weights : tuple of float
        Quadrature weights (sum 1).
    """

    nodes: tuple[float, ...]
    weights: tuple[float, ...]
    #: a much finer quadrature of the same weighting, used for the zero-lag (same beam)
    #: integral whose integrand has the r^(2/3) cusp on the diagonal z' = z''
    fine_nodes: tuple[float, ...] = ()
    fine_weights: tuple[float, ...] = ()

    @property
    def z(self) -> np.ndarray:
        return np.asarray(self.nodes)

    @property
    def w(self) -> np.ndarray:
        return np.asarray(self.weights)

    @property
    def z_fine(self) -> np.ndarray:
        return np.asarray(self.fine_nodes or self.nodes)

    @property
    def w_fine(self) -> np.ndarray:
        return np.asarray(self.fine_weights or self.weights)


def same_beam_variance(
    probe: ProbeQuadrature,
    sigma2: float,
    outer_scale: float,
    model: CorrelationModel = "exponential",
) -> float:
    """B_D(theta, theta) = int int Q(z') Q(z'') B_V(|z' - z''|) dz' dz'' (m2 s-2).

    The diagonal of Banakh et al. (1999), eq. 15 (same beam, same time: the tensor
    contracts to the longitudinal B_V), on the fine quadrature of ``probe``: the cusp
    of B_V at r = 0 makes a coarse product rule overestimate it by up to 3 %.
    """
    z, w = probe.z_fine, probe.w_fine
    b = longitudinal_correlation(np.abs(z[:, None] - z[None, :]), sigma2, outer_scale, model)
    return float(w @ b @ w)


def wind_vector(speed: float, direction_deg: float, vertical: float = 0.0) -> np.ndarray:
    """Mean wind (up, north, east) components (m s-1) for a wind blowing *from* direction.

    The (u, v) of :func:`cwproc.physics.geometry.wind_components` in the (up, north,
    east) order of Banakh et al. (1999), eq. 1.
    """
    u, v = wind_components(speed, direction_deg)
    return np.array([vertical, v, u])


@dataclass(frozen=True)
class ScanGeometry:
    """One conical scan: M azimuths sampled at times t_m (Banakh et al. (1999), section 3).

    Attributes
    ----------
    elevation_deg : float
        Elevation phi of the cone (deg).
    n_azimuths : int
        M, spectra (rays) per scan.
    scan_period_s : float
        T, duration of one 360 degree rotation (s).
    """

    elevation_deg: float
    n_azimuths: int
    scan_period_s: float

    @property
    def azimuth_deg(self) -> np.ndarray:
        """theta_m = m dtheta (deg)."""
        return np.arange(self.n_azimuths) * 360.0 / self.n_azimuths

    @property
    def time_s(self) -> np.ndarray:
        """t_m = m t0 (s), t0 = T/M."""
        return np.arange(self.n_azimuths) * self.scan_period_s / self.n_azimuths


# --------------------------------------------------------------------------------------
# B_D: azimuth correlation of the probe-averaged velocity (eq. 15)
# --------------------------------------------------------------------------------------


def azimuth_correlation_matrix(
    geometry: ScanGeometry,
    probe: ProbeQuadrature,
    *,
    sigma2: float,
    outer_scale: float,
    mean_wind: np.ndarray | None = None,
    model: CorrelationModel = "exponential",
    chunk: int = 64,
) -> np.ndarray:
    """Correlation matrix B_D(theta_m, theta_l) of the probe-averaged radial velocity.

    Banakh et al. (1999), eq. 15: the double probe-volume integral of
    S(theta_m)^T B(z' S_m - z'' S_l - <V>(t_m - t_l)) S(theta_l), B of eq. 16.
    The transport term follows Taylor's frozen-turbulence hypothesis
    V(r, t) = V'(r - <V> t), which gives the separation r_m - r_l - <V>(t_m - t_l);
    the printed '+' of eq. 15 is the opposite sign convention for <V>.

    Parameters
    ----------
    geometry : ScanGeometry
    probe : ProbeQuadrature
        Probe weighting along the beam (e.g. cw Q_s).
    sigma2, outer_scale : float
        sigma_V^2 (m2 s-2) and L_V (m).
    mean_wind : numpy.ndarray, optional
        <V> (up, north, east) (m s-1); ``None``: no transport (B_D then depends on
        theta_m - theta_l only).
    model : {"exponential", "von_karman"}
    chunk : int
        Azimuth pairs per vectorised block (memory only).

    Returns
    -------
    numpy.ndarray
        B_D, shape (M, M) (m2 s-2), symmetric.
    """
    s = beam_unit_vector_une(geometry.azimuth_deg, geometry.elevation_deg)
    t = geometry.time_s
    m_idx, l_idx = np.triu_indices(geometry.n_azimuths)
    wind = np.zeros(3) if mean_wind is None else np.asarray(mean_wind, dtype=float)
    shift = -wind[None, :] * (t[m_idx] - t[l_idx])[:, None]
    out = _pair_correlations(
        s[m_idx], s[l_idx], shift, probe, sigma2, outer_scale, model, chunk=chunk
    )
    b = np.empty((geometry.n_azimuths, geometry.n_azimuths))
    b[m_idx, l_idx] = out
    b[l_idx, m_idx] = out
    np.fill_diagonal(b, same_beam_variance(probe, sigma2, outer_scale, model))
    return b


#: relative tolerance (to the variance B_D(theta, theta)) of the azimuth interpolation
#: of :func:`interpolated_azimuth_correlation_matrix`
AZIMUTH_INTERPOLATION_TOLERANCE = 1e-4


def interpolated_azimuth_correlation_matrix(
    geometry: ScanGeometry,
    probe: ProbeQuadrature,
    *,
    sigma2: float,
    outer_scale: float,
    mean_wind: np.ndarray | None = None,
    model: CorrelationModel = "exponential",
    tolerance: float = AZIMUTH_INTERPOLATION_TOLERANCE,
    max_nodes: int = 64,
) -> np.ndarray:
    """B_D of :func:`azimuth_correlation_matrix` from fewer azimuths, by trigonometric
    interpolation along each lag (Banakh et al. (1999), eq. 15).

    For a lag k the entries B_D(theta_m, theta_m + k dtheta) share the time lag k t0 and
    hence the transport -<V> k t0; as a function of the continuous azimuth theta they
    form a smooth 2 pi-periodic function f_k(theta) (it is a constant without wind).
    f_k is evaluated by eq. 15 on n = 4, 8, 16, ... equally spaced azimuths (nested
    grids: each level adds n/2 new points) and interpolated to the theta_m by its
    discrete Fourier series; a lag is accepted at the first level whose interpolant
    differs from the previous level's by at most ``tolerance`` B_D(theta, theta) at
    every theta_m (the difference bounds the coarser level's error; the finer one is
    kept). Lags not accepted at ``max_nodes`` points, and lags with at most that many
    entries, are evaluated at their theta_m directly. The diagonal is the same-beam
    integral.

    Parameters
    ----------
    geometry, probe, sigma2, outer_scale, mean_wind, model
        As :func:`azimuth_correlation_matrix`.
    tolerance : float
        Acceptance threshold, relative to the variance of V_D.
    max_nodes : int
        Largest interpolation grid (a power of 2 times 4).

    Returns
    -------
    numpy.ndarray
        B_D, shape (M, M) (m2 s-2), symmetric.
    """
    n_az = geometry.n_azimuths
    dtheta, t0 = 2.0 * np.pi / n_az, geometry.scan_period_s / n_az
    wind = np.zeros(3) if mean_wind is None else np.asarray(mean_wind, dtype=float)
    variance = same_beam_variance(probe, sigma2, outer_scale, model)
    theta_m = np.arange(n_az) * dtheta
    lags = np.arange(1, n_az)
    rows = np.full((n_az, n_az), np.nan)  # rows[k, m] = B_D(theta_m, theta_m + k dtheta)

    def evaluate(theta: np.ndarray, lag: np.ndarray) -> np.ndarray:
        s1 = beam_unit_vector_une(np.rad2deg(theta), geometry.elevation_deg)
        s2 = beam_unit_vector_une(np.rad2deg(theta + lag * dtheta), geometry.elevation_deg)
        shift = wind[None, :] * (lag * t0)[:, None]  # -<V>(t_m - t_l), t_l - t_m = k t0
        return _pair_correlations(s1, s2, shift, probe, sigma2, outer_scale, model)

    n, values, previous = 4, None, None
    active = lags[n_az - lags > 2 * n]
    grid = np.arange(n) * 2.0 * np.pi / n
    values = evaluate(np.tile(grid, active.size), np.repeat(active, n)).reshape(active.size, n)
    previous = _trigonometric_interpolation(values, theta_m)
    while active.size and 2 * n <= max_nodes:
        n *= 2
        keep = n_az - active > n  # an interpolation grid smaller than the entries
        active, values, previous = active[keep], values[keep], previous[keep]
        new = (np.arange(n // 2) * 2.0 + 1.0) * 2.0 * np.pi / n  # the odd points of level n
        added = evaluate(np.tile(new, active.size), np.repeat(active, n // 2))
        values = np.stack([values, added.reshape(active.size, n // 2)], axis=-1).reshape(
            active.size, n
        )
        current = _trigonometric_interpolation(values, theta_m)
        done = np.max(np.abs(current - previous), axis=1) <= tolerance * variance
        rows[active[done]] = current[done]
        active, values, previous = active[~done], values[~done], current[~done]
    direct = lags[np.isnan(rows[lags, 0])]
    m_of = np.concatenate([np.arange(n_az - k) for k in direct])
    k_of = np.repeat(direct, n_az - direct)
    rows[k_of, m_of] = evaluate(theta_m[m_of], k_of)
    b = np.empty((n_az, n_az))
    for k in lags:
        m = np.arange(n_az - k)
        b[m, m + k] = b[m + k, m] = rows[k, : n_az - k]
    np.fill_diagonal(b, variance)
    return b


def _trigonometric_interpolation(values: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Trigonometric interpolant of samples on n equally spaced azimuths, at ``theta``.

    values: shape (K, n) at 2 pi j / n; n even: the Nyquist term is split between
    +-n/2 (the real interpolant of least degree). Returns shape (K, len(theta)).
    """
    n = values.shape[1]
    c = np.fft.rfft(values, axis=1) / n
    c[:, 1:] *= 2.0
    if n % 2 == 0:
        c[:, -1] *= 0.5
    freq = np.arange(c.shape[1])
    phase = np.exp(1j * np.outer(freq, theta))
    return np.real(c @ phase)


def _pair_correlations(
    s1: np.ndarray,
    s2: np.ndarray,
    shift: np.ndarray,
    probe: ProbeQuadrature,
    sigma2: float,
    outer_scale: float,
    model: CorrelationModel,
    *,
    chunk: int = 64,
) -> np.ndarray:
    """Eq. 15 of Banakh et al. (1999) for P beam pairs: the double probe integral.

    int int Q(z') Q(z'') S1^T B(z' S1 - z'' S2 + shift) S2 dz' dz'' on the product
    rule of ``probe`` (B of eq. 16), with r^2 and the projections built from per-pair
    scalars (|S| = 1), ``chunk`` pairs at a time.

    Parameters
    ----------
    s1, s2 : numpy.ndarray
        Unit beam vectors, shape (P, 3).
    shift : numpy.ndarray
        Transport term -<V>(t1 - t2), shape (P, 3) (m).

    Returns
    -------
    numpy.ndarray
        Shape (P,) (m2 s-2).
    """
    z, w = probe.z, probe.w
    ww = (w[:, None] * w[None, :]).ravel()
    z1, z2 = z[None, :, None], z[None, None, :]  # z', z''
    zz, zz_sum = z1 * z2, z1 * z1 + z2 * z2
    out = np.empty(s1.shape[0])
    for start in range(0, s1.shape[0], chunk):
        part = slice(start, start + chunk)
        sm, sl, sh = s1[part], s2[part], shift[part]  # (P, 3)
        # r = z' S_m - z'' S_l + shift with |S| = 1, from per-pair scalars, each (P, 1, 1)
        dot = np.sum(sm * sl, axis=-1)[:, None, None]
        a = np.sum(sm * sh, axis=-1)[:, None, None]
        b = np.sum(sl * sh, axis=-1)[:, None, None]
        h2 = np.sum(sh * sh, axis=-1)[:, None, None]
        r2 = zz_sum - 2.0 * dot * zz + 2.0 * (a * z1 - b * z2) + h2
        p1 = z1 - dot * z2 + a  # S_m . r
        p2 = dot * z1 - z2 + b  # S_l . r
        val = _projected_from_components(r2, dot, p1 * p2, sigma2, outer_scale, model)
        out[part] = val.reshape(val.shape[0], -1) @ ww
    return out


def _projected_from_components(
    r2: np.ndarray,
    dot: np.ndarray,
    p12: np.ndarray,
    sigma2: float,
    outer_scale: float,
    model: CorrelationModel,
) -> np.ndarray:
    """:func:`projected_correlation` from r^2, S1.S2 and (S1.r)(S2.r) (no 1/r^2 yet).

    B (S1.S2) + (r/2) B' [S1.S2 - (S1.r)(S2.r)/r^2] of eq. 16. For eq. 17 (exponential)
    with x = (r/L)^(2/3) = exp(log(r^2/L^2) / 3): g = f (1 - 1.21 x/3) and
    g - f = -1.21 x f/3, so that B = sigma^2 f [S1.S2 + (1.21 x/3)((S1.r)(S2.r)/r^2 -
    S1.S2)], without a square root or a fractional power (numpy's log and exp are
    vectorised, its cbrt is not: 3x faster than cbrt; x = 0 at r = 0 through log 0 =
    -inf, r^2 < 0 of round-off clipped to 0).
    """
    safe = np.where(r2 > 0, r2, 1.0)
    if model == "exponential":
        x = np.maximum(r2, 0.0) * (1.0 / (outer_scale * outer_scale))
        with np.errstate(divide="ignore"):
            np.log(x, out=x)
        x *= 1.0 / 3.0
        np.exp(x, out=x)
        f = np.exp(-EXPONENTIAL_COEFFICIENT * x)
        x *= EXPONENTIAL_COEFFICIENT / 3.0
        bracket = p12 / safe
        bracket -= dot
        bracket *= x
        bracket += dot
        bracket *= f
        if sigma2 != 1.0:
            bracket *= sigma2
        return bracket
    transverse, rb = _correlation_pair(np.sqrt(r2), sigma2, outer_scale, model)
    return transverse * dot - rb * p12 / safe


def circulant_correlation_row(
    geometry: ScanGeometry,
    probe: ProbeQuadrature,
    outer_scales: np.ndarray,
    model: CorrelationModel = "exponential",
    lags: np.ndarray | None = None,
) -> np.ndarray:
    """First row b_k(L) of B_D / sigma_V^2 without transport, for many outer scales.

    Without the mean-wind term B_D (Banakh et al. (1999), eq. 15) depends on the
    azimuth difference only (circulant matrix); the geometry of the double integral is
    computed once and the correlation model evaluated for every L_V.

    Parameters
    ----------
    geometry : ScanGeometry
    probe : ProbeQuadrature
    outer_scales : numpy.ndarray
        L_V values (m), shape (K,).
    model : {"exponential", "von_karman"}
    lags : numpy.ndarray, optional
        Azimuth lag numbers k to compute (default: all 0..M-1).

    Returns
    -------
    numpy.ndarray
        Shape (K, len(lags)): b_k = B_D(theta_0, theta_k) / sigma_V^2 (dimensionless).
    """
    lags = np.arange(geometry.n_azimuths) if lags is None else np.asarray(lags, dtype=int)
    s = beam_unit_vector_une(geometry.azimuth_deg[lags], geometry.elevation_deg)
    s0 = beam_unit_vector_une(geometry.azimuth_deg[:1], geometry.elevation_deg)[0]
    z, w = probe.z, probe.w
    ww = w[:, None] * w[None, :]
    r_vec = z[None, :, None, None] * s0 - z[None, None, :, None] * s[:, None, None, :]
    r = np.sqrt(np.sum(r_vec**2, axis=-1))  # (K, n, n)
    dot = s @ s0  # (K,)
    safe = np.where(r > 0, r, 1.0)
    p1 = np.sum(s0 * r_vec, axis=-1) / safe
    p2 = np.sum(s[:, None, None, :] * r_vec, axis=-1) / safe
    p12 = p1 * p2
    out = np.empty((np.size(outer_scales), lags.size))
    if model == "exponential":  # eq. 17: r^(2/3) once, exp per scale (no power per scale)
        x0 = np.cbrt(r * r)
        cusp = np.cbrt(np.subtract.outer(probe.z_fine, probe.z_fine) ** 2)
        for i, scale in enumerate(np.atleast_1d(outer_scales)):
            x = x0 / float(scale) ** (2.0 / 3.0)
            f = np.exp(-EXPONENTIAL_COEFFICIENT * x)
            cx = (EXPONENTIAL_COEFFICIENT / 3.0) * x
            val = f * ((1.0 - cx) * dot[:, None, None] + cx * p12)
            out[i] = val.reshape(val.shape[0], -1) @ ww.ravel()
            same = np.exp(-EXPONENTIAL_COEFFICIENT * cusp / float(scale) ** (2.0 / 3.0))
            out[i, lags == 0] = probe.w_fine @ same @ probe.w_fine
        return out
    for i, scale in enumerate(np.atleast_1d(outer_scales)):
        transverse_b, rb = _correlation_pair(r, 1.0, float(scale), model)
        out[i] = np.einsum("mjk,jk->m", transverse_b * dot[:, None, None] - rb * p12, ww)
        out[i, lags == 0] = same_beam_variance(probe, 1.0, float(scale), model)
    return out
