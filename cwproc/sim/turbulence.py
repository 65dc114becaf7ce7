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
(:class:`ProbeQuadrature`), e.g. :func:`cwproc.physics.cw_probe.cw_probe_quadrature` for the cw
Lorentzian Q_s.

Coordinates are (z, x, y) = (up, north, east); the beam unit vector is
S(theta) = (sin phi, cos phi cos theta, cos phi sin theta) with theta the azimuth
clockwise from north and phi the elevation (Banakh et al. (1999), eq. 1).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.fft import next_fast_len

from cwproc.physics.correlation import (
    CorrelationModel,
    ProbeQuadrature,
    ScanGeometry,
    interpolated_azimuth_correlation_matrix,
    longitudinal_correlation,
)
from cwproc.tables.store import cached_arrays


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
    geometry/probe/outer scale/wind is computed once per process, and kept on disk
    between runs (:func:`cwproc.tables.store.cached_arrays`, keyed by the SHA-256
    of every parameter: a file read the next time). B_D (eq. 15) is
    :func:`cwproc.physics.correlation.interpolated_azimuth_correlation_matrix` (entries
    within 1e-4 of the variance of the exact matrix by construction, 1e-6 measured for
    the cw lidar of Banakh et al. (1999); 0.2-0.4 s per height instead of 0.7-1.1 s).

    Returns
    -------
    numpy.ndarray
        Lower-triangular (M, M), read-only.
    """
    m = geometry.n_azimuths

    def compute() -> dict[str, np.ndarray]:
        b = interpolated_azimuth_correlation_matrix(
            geometry,
            probe,
            sigma2=1.0,
            outer_scale=outer_scale,
            mean_wind=None if wind is None else np.asarray(wind),
            model=model,
        )
        return {"factor": cholesky_factor(b)}

    def valid(arrays: dict[str, np.ndarray]) -> bool:
        a = arrays.get("factor")
        return a is not None and a.shape == (m, m) and bool(np.isfinite(a).all())

    params = {
        "numerics": _CHOLESKY_NUMERICS,
        "geometry": [geometry.elevation_deg, m, geometry.scan_period_s],
        "probe": [probe.nodes, probe.weights, probe.fine_nodes, probe.fine_weights],
        "outer_scale": float(outer_scale),
        "wind": None if wind is None else [float(x) for x in wind],
        "model": model,
    }
    a = cached_arrays("scan-cholesky", params, compute, valid)["factor"]
    a.setflags(write=False)
    return a


#: version of the numerics of :func:`scan_cholesky` (eq. 15 quadrature, jitter): a change
#: of the computation changes the cache key, so that old factors are never served
_CHOLESKY_NUMERICS = 2


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
    big = next_fast_len(2 * n)
    lam = along_beam_spectrum(big, dr, sigma2, outer_scale, model)
    total = int(np.prod(size)) if size else 1
    half = (total + 1) // 2  # real and imaginary parts are independent realisations
    xi = rng.standard_normal((half, big)) + 1j * rng.standard_normal((half, big))
    field = np.fft.fft(xi * np.sqrt(lam / big), axis=-1)[:, :n]
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
    nfft = next_fast_len(n + k, real=True)
    qf = np.conj(np.fft.rfft(weights, nfft))
    c1 = np.fft.irfft(np.fft.rfft(series, nfft, axis=-1) * qf, nfft, axis=-1)
    c2 = np.fft.irfft(np.fft.rfft(series * series, nfft, axis=-1) * qf, nfft, axis=-1)
    mean = c1[..., offsets]
    return mean, np.maximum(c2[..., offsets] - mean * mean, 0.0)
