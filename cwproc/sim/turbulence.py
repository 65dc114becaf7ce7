"""Random wind fields of the virtual instrument (Banakh et al. (1999), eqs. 15-23).

Two processes are simulated separately, as in Banakh et al. (1999), section 2:

* the *scan-scale* velocity V_D(theta_m) -- the radial velocity averaged over the
  probe volume -- at the M azimuths of a conical scan, by the linear transformation
  (Cholesky factor) of its azimuth correlation matrix B_D (eqs. 15, 20-21). B_D is the
  double probe-volume integral of the isotropic correlation tensor (eq. 16) of the
  longitudinal correlation model (eq. 17, or von Karman), including the transport of
  the frozen field by the mean wind between the azimuths;
* the *small-scale* along-beam fluctuation V~_r(i dr) by FFT (eqs. 22-23), from which
  the deviations Delta V_r inside the probe volume follow (eq. 14).

The probe volume enters only through quadrature nodes and weights along the beam
(:class:`ProbeQuadrature`), e.g. :func:`cwproc.sim.cw.cw_probe_quadrature` for the cw
Lorentzian Q_s.

Coordinates are (z, x, y) = (up, north, east); the beam unit vector is
S(theta) = (sin phi, cos phi cos theta, cos phi sin theta) with theta the azimuth
clockwise from north and phi the elevation (Banakh et al. (1999), eq. 1).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.fft
from scipy import special

#: Kolmogorov constant C_k of the longitudinal structure function, Banakh et al. (1999), eq. 18
KOLMOGOROV_CK = 2.0
#: the exponent coefficient of Banakh et al. (1999), eq. 17
EQ17_COEFFICIENT = 1.21

CorrelationModel = Literal["exponential", "von_karman"]

#: integral scale of the von Karman longitudinal correlation in units of its length l
_VK_INTEGRAL_SCALE = float(np.sqrt(np.pi) * special.gamma(5.0 / 6.0) / special.gamma(1.0 / 3.0))


# --------------------------------------------------------------------------------------
# correlation models
# --------------------------------------------------------------------------------------


def exponential_correlation(r: np.ndarray, sigma2: float, outer_scale: float) -> np.ndarray:
    """Longitudinal correlation B_V(r) = sigma^2 exp[-1.21 (r/L_V)^(2/3)].

    Banakh et al. (1999), eq. 17. Its integral scale int_0^inf B_V dr / sigma^2 is
    (3/2) Gamma(3/2) 1.21^(-3/2) L_V = 0.9987 L_V.

    Parameters
    ----------
    r : numpy.ndarray
        Separation (m), >= 0.
    sigma2 : float
        Velocity variance sigma_V^2 (m2 s-2).
    outer_scale : float
        Integral scale L_V (m).

    Returns
    -------
    numpy.ndarray
        B_V(r) (m2 s-2).
    """
    return sigma2 * np.exp(-EQ17_COEFFICIENT * (np.abs(r) / outer_scale) ** (2.0 / 3.0))


def von_karman_correlation(r: np.ndarray, sigma2: float, outer_scale: float) -> np.ndarray:
    """Longitudinal von Karman correlation with integral scale L_V.

    B_V(r) = sigma^2 2^(2/3)/Gamma(1/3) x^(1/3) K_(1/3)(x), x = r/l,
    l = L_V Gamma(1/3) / (sqrt(pi) Gamma(5/6)) (Lumley and Panofsky, cited as [13] by
    Banakh et al. (1999)).

    Parameters
    ----------
    r : numpy.ndarray
        Separation (m).
    sigma2 : float
        Velocity variance (m2 s-2).
    outer_scale : float
        Integral scale L_V (m).

    Returns
    -------
    numpy.ndarray
        B_V(r) (m2 s-2).
    """
    x = np.abs(np.asarray(r, dtype=float)) / (outer_scale / _VK_INTEGRAL_SCALE)
    with np.errstate(invalid="ignore"):
        f = (
            2.0 ** (2.0 / 3.0)
            / special.gamma(1.0 / 3.0)
            * x ** (1.0 / 3.0)
            * special.kv(1.0 / 3.0, x)
        )
    return sigma2 * np.where(x > 0, f, 1.0)


def correlation_derivative(
    r: np.ndarray, sigma2: float, outer_scale: float, model: CorrelationModel
) -> np.ndarray:
    """dB_V/dr of the longitudinal correlation model (m s-2 per m), r > 0.

    eq. 17: dB/dr = -(2/3) 1.21 (r/L)^(-1/3) B / L; von Karman:
    d/dx [x^nu K_nu(x)] = -x^nu K_(nu-1)(x) with nu = 1/3.
    """
    r = np.asarray(r, dtype=float)
    if model == "exponential":
        rr = np.maximum(r, 1e-300)
        b = exponential_correlation(rr, sigma2, outer_scale)
        return (
            -(2.0 / 3.0) * EQ17_COEFFICIENT * (rr / outer_scale) ** (-1.0 / 3.0) * b / outer_scale
        )
    length = outer_scale / _VK_INTEGRAL_SCALE
    x = np.maximum(r / length, 1e-300)
    c = 2.0 ** (2.0 / 3.0) / special.gamma(1.0 / 3.0)
    return -sigma2 * c * x ** (1.0 / 3.0) * special.kv(-2.0 / 3.0, x) / length


def longitudinal_correlation(
    r: np.ndarray, sigma2: float, outer_scale: float, model: CorrelationModel = "exponential"
) -> np.ndarray:
    """B_V(r) of the chosen model (``"exponential"``: eq. 17; ``"von_karman"``)."""
    if model == "exponential":
        return exponential_correlation(r, sigma2, outer_scale)
    if model == "von_karman":
        return von_karman_correlation(r, sigma2, outer_scale)
    raise ValueError(f"unknown correlation model {model!r}")


def integral_scale_coefficient(model: CorrelationModel = "exponential") -> float:
    """The coefficient c of L_V = c sigma_V^3 / epsilon, Banakh et al. (1999), eq. 19.

    From D_V(r) = 2[sigma^2 - B_V(r)] -> C_k epsilon^(2/3) r^(2/3) for r << L_V
    (eq. 18, C_k = 2): c = (2 * 1.21 / C_k)^(3/2) = 1.331 for eq. 17 (the paper: 1.33);
    for von Karman c = [2^(1/3) Gamma(2/3) / (Gamma(4/3) C_k)]^(3/2) sqrt(pi)
    Gamma(5/6)/Gamma(1/3) = 0.697 (the paper rounds it to 0.67).
    """
    if model == "exponential":
        return (2.0 * EQ17_COEFFICIENT / KOLMOGOROV_CK) ** 1.5
    if model == "von_karman":
        a = 2.0 ** (1.0 / 3.0) * special.gamma(2.0 / 3.0) / special.gamma(4.0 / 3.0)
        return float((a / KOLMOGOROV_CK) ** 1.5 * _VK_INTEGRAL_SCALE)
    raise ValueError(f"unknown correlation model {model!r}")


def epsilon_from_variance(
    sigma2: float | np.ndarray,
    outer_scale: float | np.ndarray,
    model: CorrelationModel = "exponential",
) -> np.ndarray:
    """epsilon = c sigma_V^3 / L_V (m2 s-3), Banakh et al. (1999), eq. 19."""
    return integral_scale_coefficient(model) * np.asarray(sigma2) ** 1.5 / np.asarray(outer_scale)


def variance_from_epsilon(
    epsilon: float | np.ndarray,
    outer_scale: float | np.ndarray,
    model: CorrelationModel = "exponential",
) -> np.ndarray:
    """sigma_V^2 = (epsilon L_V / c)^(2/3) (m2 s-2), inverse of Banakh et al. (1999), eq. 19."""
    c = integral_scale_coefficient(model)
    return (np.asarray(epsilon) * np.asarray(outer_scale) / c) ** (2.0 / 3.0)


def correlation_tensor(
    r_vec: np.ndarray, sigma2: float, outer_scale: float, model: CorrelationModel = "exponential"
) -> np.ndarray:
    """Isotropic solenoidal correlation tensor B_ik(r), Banakh et al. (1999), eq. 16.

    B_ik(r) = B_V(r) delta_ik + (r/2) dB_V/dr (delta_ik - r_i r_k / r^2).

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
    b = longitudinal_correlation(r, sigma2, outer_scale, model)
    rb = np.where(r > 0, 0.5 * r * correlation_derivative(r, sigma2, outer_scale, model), 0.0)
    unit = np.where(r[..., None] > 0, r_vec / np.where(r > 0, r, 1.0)[..., None], 0.0)
    eye = np.eye(3)
    return (b + rb)[..., None, None] * eye - rb[..., None, None] * (
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
    b = longitudinal_correlation(r, sigma2, outer_scale, model)
    rb = np.where(r > 0, 0.5 * r * correlation_derivative(r, sigma2, outer_scale, model), 0.0)
    return b * dot + rb * (dot - p1 * p2)


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


def beam_vectors(azimuth_deg: np.ndarray, elevation_deg: float | np.ndarray) -> np.ndarray:
    """Unit beam vectors S(theta) = (sin phi, cos phi cos theta, cos phi sin theta).

    Banakh et al. (1999), eq. 1, in (up, north, east) with theta clockwise from north.

    Returns
    -------
    numpy.ndarray
        Shape (M, 3).
    """
    th = np.deg2rad(np.asarray(azimuth_deg, dtype=float))
    ph = np.deg2rad(np.broadcast_to(np.asarray(elevation_deg, dtype=float), th.shape))
    return np.stack([np.sin(ph), np.cos(ph) * np.cos(th), np.cos(ph) * np.sin(th)], axis=-1)


def wind_vector(speed: float, direction_deg: float, vertical: float = 0.0) -> np.ndarray:
    """Mean wind (up, north, east) components (m s-1) for a wind blowing *from* direction."""
    d = np.deg2rad(direction_deg)
    return np.array([vertical, -speed * np.cos(d), -speed * np.sin(d)])


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
    chunk: int = 256,
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
    s = beam_vectors(geometry.azimuth_deg, geometry.elevation_deg)
    t = geometry.time_s
    z, w = probe.z, probe.w
    ww = w[:, None] * w[None, :]
    m_idx, l_idx = np.triu_indices(geometry.n_azimuths)
    wind = np.zeros(3) if mean_wind is None else np.asarray(mean_wind, dtype=float)
    out = np.empty(m_idx.size)
    for start in range(0, m_idx.size, chunk):
        mi, li = m_idx[start : start + chunk], l_idx[start : start + chunk]
        sm, sl = s[mi], s[li]  # (P, 3)
        shift = -wind[None, :] * (t[mi] - t[li])[:, None]  # (P, 3)
        r_vec = (
            z[None, :, None, None] * sm[:, None, None, :]
            - z[None, None, :, None] * sl[:, None, None, :]
            + shift[:, None, None, :]
        )  # (P, n, n, 3)
        val = projected_correlation(
            r_vec, sm[:, None, None, :], sl[:, None, None, :], sigma2, outer_scale, model
        )
        out[start : start + chunk] = np.einsum("pjk,jk->p", val, ww)
    b = np.empty((geometry.n_azimuths, geometry.n_azimuths))
    b[m_idx, l_idx] = out
    b[l_idx, m_idx] = out
    np.fill_diagonal(b, same_beam_variance(probe, sigma2, outer_scale, model))
    return b


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
    s = beam_vectors(geometry.azimuth_deg[lags], geometry.elevation_deg)
    s0 = beam_vectors(geometry.azimuth_deg[:1], geometry.elevation_deg)[0]
    z, w = probe.z, probe.w
    ww = w[:, None] * w[None, :]
    r_vec = z[None, :, None, None] * s0 - z[None, None, :, None] * s[:, None, None, :]
    r = np.sqrt(np.sum(r_vec**2, axis=-1))  # (K, n, n)
    dot = s @ s0  # (K,)
    safe = np.where(r > 0, r, 1.0)
    p1 = np.sum(s0 * r_vec, axis=-1) / safe
    p2 = np.sum(s[:, None, None, :] * r_vec, axis=-1) / safe
    transverse = dot[:, None, None] - p1 * p2
    out = np.empty((np.size(outer_scales), lags.size))
    for i, scale in enumerate(np.atleast_1d(outer_scales)):
        b = longitudinal_correlation(r, 1.0, float(scale), model)
        rb = np.where(r > 0, 0.5 * r * correlation_derivative(r, 1.0, float(scale), model), 0.0)
        out[i] = np.einsum("mjk,jk->m", b * dot[:, None, None] + rb * transverse, ww)
        out[i, lags == 0] = same_beam_variance(probe, 1.0, float(scale), model)
    return out


def cholesky_factor(b: np.ndarray, jitter: float = 1e-10) -> np.ndarray:
    """Lower-triangular a with B = a a^T, Banakh et al. (1999), eq. 21.

    A relative diagonal jitter keeps the factorisation stable when B_D is nearly
    singular (strongly correlated neighbouring azimuths).
    """
    scale = float(np.mean(np.diag(b)))
    eye = np.eye(b.shape[0])
    for k in range(6):
        try:
            return np.linalg.cholesky(b + eye * scale * jitter * 10.0**k)
        except np.linalg.LinAlgError:
            continue
    raise np.linalg.LinAlgError("B_D is not positive definite")


@functools.lru_cache(maxsize=64)
def scan_cholesky(
    geometry: ScanGeometry,
    probe: ProbeQuadrature,
    outer_scale: float,
    wind: tuple[float, float, float] | None,
    model: CorrelationModel = "exponential",
) -> np.ndarray:
    """Cached Cholesky factor of B_D for unit variance, per (height, configuration).

    Parameters are hashable (frozen dataclasses, tuples) so that the factor of each
    geometry/probe/outer scale/wind is computed once per process.

    Returns
    -------
    numpy.ndarray
        Lower-triangular (M, M), read-only.
    """
    b = azimuth_correlation_matrix(
        geometry,
        probe,
        sigma2=1.0,
        outer_scale=outer_scale,
        mean_wind=None if wind is None else np.asarray(wind),
        model=model,
    )
    a = cholesky_factor(b)
    a.setflags(write=False)
    return a


def simulate_scan_velocities(
    rng: np.random.Generator, factor: np.ndarray, sigma2: float, size: tuple[int, ...]
) -> np.ndarray:
    """Random V~_D(theta_m) = sum_m' a_mm' xi_m', Banakh et al. (1999), eq. 20.

    Parameters
    ----------
    rng : numpy.random.Generator
    factor : numpy.ndarray
        Cholesky factor of B_D for unit variance, (M, M).
    sigma2 : float
        sigma_V^2 (m2 s-2).
    size : tuple of int
        Leading shape, e.g. (realisations, scans).

    Returns
    -------
    numpy.ndarray
        Fluctuations, shape size + (M,) (m s-1); add the mean S(theta_m).<V>.
    """
    m = factor.shape[0]
    xi = rng.standard_normal((int(np.prod(size)) if size else 1, m))
    return (np.sqrt(sigma2) * xi @ factor.T).reshape(*size, m)


# --------------------------------------------------------------------------------------
# small-scale along-beam fluctuations by FFT (eqs. 22-23)
# --------------------------------------------------------------------------------------


def along_beam_spectrum(
    n: int, dr: float, sigma2: float, outer_scale: float, model: CorrelationModel = "exponential"
) -> np.ndarray:
    """Eigenvalues of the periodic (circulant) covariance of B_V on n points, step dr.

    The discrete counterpart of S_V(k/(N dr)) of Banakh et al. (1999), eq. 22: the FFT
    of B_V(min(i, n-i) dr). Negative round-off values are set to 0.

    Returns
    -------
    numpy.ndarray
        Shape (n,) (m2 s-2 per mode).
    """
    i = np.arange(n)
    lag = np.minimum(i, n - i) * dr
    lam = np.fft.fft(longitudinal_correlation(lag, sigma2, outer_scale, model)).real
    return np.maximum(lam, 0.0)


def along_beam_fluctuations(
    rng: np.random.Generator,
    n: int,
    dr: float,
    sigma2: float,
    outer_scale: float,
    size: tuple[int, ...] = (),
    model: CorrelationModel = "exponential",
) -> np.ndarray:
    """Along-beam radial-velocity fluctuations V~_r(i dr), Banakh et al. (1999), eq. 23.

    Spectral synthesis: V~_r(i dr) = Re sum_k xi_k [lambda_k / N]^(1/2) exp(-2 pi i k i/N)
    with complex Gaussian xi_k (<xi_k xi_k'> = 0, <xi_k xi_k'*> = 2 delta_kk', i.e. unit
    real and imaginary parts) on a periodic grid of N = 2n points (circulant
    embedding); the first n points are kept, so that the covariance equals B_V
    (eq. 17) exactly for all lags < n dr. The paper's factor 1/(2 N dr) S_V belongs
    to its normalisation of S_V (eq. 22); here lambda_k is the discrete spectrum.

    Parameters
    ----------
    rng : numpy.random.Generator
    n : int
        Points along the beam.
    dr : float
        Step (m).
    sigma2, outer_scale : float
        sigma_V^2 (m2 s-2), L_V (m).
    size : tuple of int
        Leading shape of independent realisations.

    Returns
    -------
    numpy.ndarray
        Shape size + (n,) (m s-1).
    """
    big = scipy.fft.next_fast_len(2 * n)
    lam = along_beam_spectrum(big, dr, sigma2, outer_scale, model)
    total = int(np.prod(size)) if size else 1
    half = (total + 1) // 2  # real and imaginary parts are independent realisations
    xi = rng.standard_normal((half, big)) + 1j * rng.standard_normal((half, big))
    field = scipy.fft.fft(xi * np.sqrt(lam / big), axis=-1, workers=-1)[:, :n]
    both = np.concatenate([field.real, field.imag], axis=0)[:total]
    return both.reshape(*size, n)


def probe_weighted_moments(
    series: np.ndarray, weights: np.ndarray, offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Probe-weighted mean and variance of a series at many offsets.

    mean_m = sum_i q_i x(o_m + i), var_m = sum_i q_i x(o_m + i)^2 - mean_m^2: the
    subtraction of Banakh et al. (1999), eq. 14 and the squared turbulent width of the
    Doppler spectrum. Computed as FFT correlations (O(n log n) for all offsets).

    Parameters
    ----------
    series : numpy.ndarray
        Shape (..., n).
    weights : numpy.ndarray
        q_i (sum 1), shape (k,), k <= n.
    offsets : numpy.ndarray
        Start indices o_m with o_m + k <= n.

    Returns
    -------
    (mean, var) : numpy.ndarray
        Each of shape (..., len(offsets)).
    """
    n = series.shape[-1]
    k = weights.size
    nfft = scipy.fft.next_fast_len(n + k, real=True)
    qf = np.conj(scipy.fft.rfft(weights, nfft))
    c1 = scipy.fft.irfft(scipy.fft.rfft(series, nfft, axis=-1) * qf, nfft, axis=-1, workers=-1)
    c2 = scipy.fft.irfft(
        scipy.fft.rfft(series * series, nfft, axis=-1) * qf, nfft, axis=-1, workers=-1
    )
    mean = c1[..., offsets]
    return mean, np.maximum(c2[..., offsets] - mean * mean, 0.0)
