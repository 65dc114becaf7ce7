"""Monte-Carlo error study of Banakh et al. (1999): relative errors of epsilon, sigma_V^2, L_V vs N.

Banakh et al. (1999), section 3, Figs. 5-7: for each height of the paper's table the
virtual cw lidar (T = 7 s, 140 spectra per scan, phi = 30 deg, lambda = 10.6 um,
a0 = 7.5 cm) makes N = 1..10 independent scans; epsilon, sigma_V^2 and L_V are
estimated from them; 1000 realisations give the relative RMS errors
sigma_eps = <(eps^ - eps)^2>^(1/2) / eps and likewise for sigma_V^2 and L_V.

What is simulated (per realisation, height and scan):

* V_D(theta_m), the probe-averaged radial velocity, exactly by eq. 15 + Cholesky
  (eqs. 20-21) with the corrected, cut Lorentzian Q_s and the mean-wind transport;
* the squared turbulent width of each Doppler spectrum,
  sum_i q_i Delta V_r(i)^2 with Delta V_r of eq. 14 from an along-beam FFT series
  (eq. 23);
* spectra whose peak lies below 1 m s-1 are dropped (section 3). Under conditions
  (5)-(10) the centroid of eq. 4 equals V_D (eq. 11), which
  ``tests/sim/test_cw.py`` checks on full spectra; the study therefore uses V_D
  directly instead of 8 million simulated spectra.

The retrieval (this module's own, stated here as the task asks): the azimuth
structure function D_L(l dtheta), l = 1..3 (l dtheta <= 9 deg), of the deviations from
the N-scan VAD fit
(Smalikho (2020), eqs. 1-2), fitted by least squares with the *exact* model of eq. 17
averaged over the probe volume, D_L(l) = 2 sigma^2 [b_0(L) - b_l(L)] with b_k the
azimuth correlation of eq. 15 for unit variance (no transport: mu = U/V_s = 0.01-0.09
here). The fit gives (sigma^2, L); epsilon = 1.33 sigma^3 / L (eq. 19). The inertial-range
A-functions would bias epsilon low by 28-68 % at these heights (the probe length
and the lags are not << L_V). The variance is the paper's estimate: the mean squared
turbulent width of the spectra plus the variance of V_D about the N-scan VAD fit,
divided by its expectation factor 1 - tr(H B_D)/(N M) (H: hat matrix of the sine fit),
evaluated at L = 1.33 sigma^3/eps (fixed point); then L_V^ = 1.33 sigma^3^ / eps^
(eq. 19).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from cwproc import progress
from cwproc.config import SimulationConfig
from cwproc.physics.correlation import (
    ProbeQuadrature,
    ScanGeometry,
    circulant_correlation_row,
    wind_vector,
)
from cwproc.physics.cw_probe import cw_probe_quadrature, probe_grid
from cwproc.physics.dissipation import epsilon_from_integral_scale
from cwproc.physics.exact_lag import fit_correlation_shape
from cwproc.physics.geometry import beam_unit_vector_une
from cwproc.physics.spectra import integral_scale_coefficient
from cwproc.sim.cw import CWLidar, along_beam_offsets
from cwproc.sim.turbulence import (
    along_beam_fluctuations,
    probe_weighted_moments,
    scan_cholesky,
    simulate_scan_velocities,
)

#: outer scales (m) of the fit grid; log-spaced, 6 % apart
FIT_SCALES = np.geomspace(5.0, 5.0e4, 160)
#: outer scales (m) at which the variance-expectation factor is tabulated
FACTOR_SCALES = np.geomspace(5.0, 5.0e4, 25)
#: realisations simulated at once (memory bound of the along-beam series)
_BATCH = 250


@dataclass(frozen=True)
class HeightModel:
    """Everything the study needs at one height (computed once).

    Attributes
    ----------
    height_m, focus_range_m : float
    geometry : ScanGeometry
    quadrature : ProbeQuadrature
        Q_s quadrature for eq. 15.
    design : numpy.ndarray
        VAD design matrix rows S(theta_m), (M, 3).
    lag_model : numpy.ndarray
        D_L(l) / sigma^2 = 2 (b_0 - b_l) on :data:`FIT_SCALES`, shape (K, max_lag).
    projected : numpy.ndarray
        tr(H B_D) / sigma^2 of the single-scan sine fit on :data:`FACTOR_SCALES`.
    """

    height_m: float
    focus_range_m: float
    geometry: ScanGeometry
    quadrature: ProbeQuadrature
    design: np.ndarray
    lag_model: np.ndarray
    projected: np.ndarray


def lidar_from_config(sim: SimulationConfig, wavelength_m: float, beam_radius_m: float) -> CWLidar:
    """The virtual cw lidar of a ``[simulation]`` config section."""
    return CWLidar(
        wavelength_m=wavelength_m,
        beam_radius_m=beam_radius_m,
        elevation_deg=sim.elevation_deg,
        scan_period_s=sim.scan_period_s,
        spectra_per_scan=round(sim.scan_period_s / sim.spectrum_time_s),
        velocity_resolution_m_s=sim.velocity_resolution_m_s,
        n_channels=sim.n_channels,
        homodyne=True,
    )


def height_model(lidar: CWLidar, height_m: float, max_lag: int) -> HeightModel:
    """Probe quadrature, structure-function model and variance factor at one height.

    The structure-function model is Banakh et al. (1999), eqs. 15-17 without transport
    (circulant B_D): D_L(l)/sigma^2 = 2 [b_0(L) - b_l(L)]. tr(H B_D) of the sine fit
    (span of 1, cos theta, sin theta = Fourier modes 0, +-1 of the circulant) is
    lambda_0 + 2 lambda_1 with lambda_j the DFT of the first row.
    """
    focus = height_m / np.sin(np.deg2rad(lidar.elevation_deg))
    quad = cw_probe_quadrature(focus, lidar.wavelength_m, lidar.beam_radius_m, n_fine=300)
    geometry = lidar.geometry
    rows = circulant_correlation_row(geometry, quad, FIT_SCALES, lags=np.arange(max_lag + 1))
    lag_model = 2.0 * (rows[:, :1] - rows[:, 1:])
    full = circulant_correlation_row(geometry, quad, FACTOR_SCALES)
    spectrum = np.fft.fft(full, axis=1).real
    projected = spectrum[:, 0] + 2.0 * spectrum[:, 1]
    design = beam_unit_vector_une(geometry.azimuth_deg, lidar.elevation_deg)
    return HeightModel(float(height_m), float(focus), geometry, quad, design, lag_model, projected)


# --------------------------------------------------------------------------------------
# statistics of the simulated scans, vectorised over realisations and N
# --------------------------------------------------------------------------------------


def cumulative_vad_statistics(
    vd: np.ndarray, valid: np.ndarray, design: np.ndarray, max_lag: int
) -> dict[str, np.ndarray]:
    """VAD fits and structure functions of the first N scans, for every N at once.

    The fit V_r = S(theta).V over the valid rays of scans 1..N (Smalikho (2020), eq. 1)
    and D_L(l) = <[V'(m + l) - V'(m)]^2> over valid pairs of those scans, with
    V' = V_D - S.V^_N (Smalikho (2020), eqs. 1-2), by cumulative sums: the squared
    difference expands into sums over Delta V_D and Delta S that do not depend on V^_N.

    Parameters
    ----------
    vd : numpy.ndarray
        V_D, shape (R, N, M) (m s-1).
    valid : numpy.ndarray
        bool, same shape.
    design : numpy.ndarray
        S(theta_m), (M, 3).
    max_lag : int

    Returns
    -------
    dict
        ``wind`` (R, N, 3), ``residual_variance`` (R, N), ``structure`` (R, N, max_lag),
        ``n_valid`` (R, N).
    """
    x = design
    y = np.where(valid, vd, 0.0)
    vf = valid.astype(float)
    gram = np.cumsum(np.einsum("rnm,mi,mj->rnij", vf, x, x), axis=1)
    rhs = np.cumsum(np.einsum("rnm,mi->rni", y, x), axis=1)
    y2 = np.cumsum(np.sum(y * y, axis=-1), axis=1)
    count = np.cumsum(vf.sum(axis=-1), axis=1)
    wind = np.linalg.solve(gram, rhs[..., None])[..., 0]
    rss = (
        y2
        - 2.0 * np.einsum("rni,rni->rn", wind, rhs)
        + np.einsum("rni,rnij,rnj->rn", wind, gram, wind)
    )
    structure = np.empty((*vd.shape[:2], max_lag))
    for lag in range(1, max_lag + 1):
        pair = vf[..., lag:] * vf[..., :-lag]
        dy = (vd[..., lag:] - vd[..., :-lag]) * pair
        dx = x[lag:] - x[:-lag]  # (M - l, 3)
        s0 = np.cumsum(np.sum(dy * dy, axis=-1), axis=1)
        s1 = np.cumsum(np.einsum("rnm,mi->rni", dy, dx), axis=1)
        s2 = np.cumsum(np.einsum("rnm,mi,mj->rnij", pair, dx, dx), axis=1)
        npair = np.cumsum(pair.sum(axis=-1), axis=1)
        total = (
            s0
            - 2.0 * np.einsum("rni,rni->rn", wind, s1)
            + np.einsum("rni,rnij,rnj->rn", wind, s2, wind)
        )
        structure[..., lag - 1] = total / npair
    return {
        "wind": wind,
        "residual_variance": np.maximum(rss, 0.0) / count,
        "structure": structure,
        "n_valid": count,
    }


def fit_correlation_model(
    structure: np.ndarray, lag_model: np.ndarray, scales: np.ndarray = FIT_SCALES
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares fit of D_L(l) = sigma^2 d(l; L) over a grid of outer scales.

    :func:`cwproc.physics.exact_lag.fit_correlation_shape` without the noise term (the
    study uses the exact V_D). Model: Banakh et al. (1999), eqs. 15-17 (see
    :func:`height_model`).

    Parameters
    ----------
    structure : numpy.ndarray
        Measured D_L, shape (..., max_lag) (m2 s-2).
    lag_model : numpy.ndarray
        d(l; L) on ``scales``, shape (K, max_lag).
    scales : numpy.ndarray
        The L grid (m), shape (K,).

    Returns
    -------
    (sigma2, outer_scale) : numpy.ndarray
        Fitted sigma_V^2 (m2 s-2) and L_V (m), shape (...).
    """
    sigma2, outer_scale, _ = fit_correlation_shape(structure, lag_model, scales)
    return sigma2, outer_scale


def variance_factor(outer_scale: np.ndarray, n_scans: np.ndarray, model: HeightModel) -> np.ndarray:
    """E[raw variance estimate] / sigma_V^2 = 1 - tr(H B_D)/(N M sigma^2).

    The VAD fit of N independent scans removes tr(H B_D) of the N tr(B_D) scan-scale
    variance (H the single-scan hat matrix); the squared spectral widths hold the rest
    of sigma_V^2 - B_D(0). Interpolated in log L from :attr:`HeightModel.projected`.
    """
    proj = np.interp(np.log(outer_scale), np.log(FACTOR_SCALES), model.projected)
    return 1.0 - proj / (n_scans * model.geometry.n_azimuths)


def estimate_parameters(
    stats: dict[str, np.ndarray], width2: np.ndarray, model: HeightModel
) -> dict[str, np.ndarray]:
    """epsilon, sigma_V^2 and L_V estimates from the statistics of N scans.

    Parameters
    ----------
    stats : dict
        Output of :func:`cumulative_vad_statistics`.
    width2 : numpy.ndarray
        Mean squared turbulent spectral width of the valid spectra of scans 1..N,
        shape (R, N) (m2 s-2).
    model : HeightModel

    Returns
    -------
    dict
        ``epsilon``, ``variance``, ``integral_scale``, each (R, N).
    """
    c = integral_scale_coefficient("exponential")
    sigma2_fit, scale_fit = fit_correlation_model(stats["structure"], model.lag_model)
    epsilon = epsilon_from_integral_scale(np.maximum(sigma2_fit, 0.0), scale_fit)
    raw = stats["residual_variance"] + width2
    n = np.arange(1, raw.shape[1] + 1)[None, :]
    variance = raw
    for _ in range(4):  # fixed point: the factor depends weakly on L = c sigma^3/eps
        scale = np.clip(c * variance**1.5 / epsilon, FACTOR_SCALES[0], FACTOR_SCALES[-1])
        variance = raw / variance_factor(scale, n, model)
    return {
        "epsilon": epsilon,
        "variance": variance,
        "integral_scale": c * variance**1.5 / epsilon,
    }


# --------------------------------------------------------------------------------------
# the study
# --------------------------------------------------------------------------------------


def simulate_height(
    rng: np.random.Generator,
    lidar: CWLidar,
    model: HeightModel,
    *,
    wind_speed: float,
    wind_direction_deg: float,
    sigma2: float,
    outer_scale_m: float,
    realisations: int,
    n_scans: int,
    min_peak_velocity: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """V_D, validity and squared turbulent widths of independent scans at one height.

    Banakh et al. (1999), eqs. 13-15, 20-23 (see the module notes).

    Returns
    -------
    (vd, valid, width2) : numpy.ndarray
        Each of shape (realisations, n_scans, M).
    """
    wind = wind_vector(wind_speed, wind_direction_deg)
    factor = scan_cholesky(model.geometry, model.quadrature, float(outer_scale_m), tuple(wind))
    s = beam_unit_vector_une(model.geometry.azimuth_deg, lidar.elevation_deg)
    vd = s @ wind + simulate_scan_velocities(rng, factor, sigma2, (realisations, n_scans))
    valid = np.abs(vd) >= min_peak_velocity
    dr, q = probe_grid(model.focus_range_m, lidar.wavelength_m, lidar.beam_radius_m)
    offsets = along_beam_offsets(model.focus_range_m, lidar.elevation_deg, s.shape[0], dr)
    n = int(offsets[-1] + q.size + 1)
    width2 = np.empty_like(vd)
    for start in range(0, realisations, _BATCH):
        stop = min(start + _BATCH, realisations)
        series = along_beam_fluctuations(rng, n, dr, sigma2, outer_scale_m, (stop - start, n_scans))
        _, var = probe_weighted_moments(series, q, offsets)
        width2[start:stop] = var
    return vd, valid, width2


def run_study(
    sim: SimulationConfig,
    *,
    wavelength_m: float = 10.6e-6,
    beam_radius_m: float = 0.075,
    realisations: int | None = None,
    seed: int = 0,
) -> xr.Dataset:
    """The Monte-Carlo error study of Banakh et al. (1999), section 3, Figs. 5-7.

    Parameters
    ----------
    sim : SimulationConfig
        Geometry, heights and profiles (defaults: Banakh et al. (1999), table).
    wavelength_m, beam_radius_m : float
        lambda and a0 (m).
    realisations : int, optional
        Overrides ``sim.realisations``.
    seed : int
        Seed of the random generator (one stream per height, spawned from it).

    Returns
    -------
    xarray.Dataset
        dims ``(n_scans, height)``: ``epsilon_rel_error``, ``variance_rel_error``,
        ``integral_scale_rel_error`` (fractions) and ``epsilon_mean_ratio`` (mean
        eps^/eps, the bias); truth profiles per height.
    """
    lidar = lidar_from_config(sim, wavelength_m, beam_radius_m)
    n_real = int(realisations or sim.realisations)
    n_max = sim.max_scans
    heights = np.asarray(sim.heights_m, dtype=float)
    streams = np.random.SeedSequence(seed).spawn(heights.size)
    shape = (n_max, heights.size)
    out = {k: np.empty(shape) for k in ("eps", "var", "scale", "ratio", "n_valid")}
    truth_eps = np.empty(heights.size)
    for j, h in progress.track(list(enumerate(heights)), desc="heights", unit="height"):
        sigma2 = float(sim.sigma_v_m_s[j]) ** 2
        scale = float(sim.outer_scale_m[j])
        eps = float(epsilon_from_integral_scale(sigma2, scale))
        truth_eps[j] = eps
        model = height_model(lidar, float(h), sim.max_lag)
        vd, valid, width2 = simulate_height(
            np.random.default_rng(streams[j]),
            lidar,
            model,
            wind_speed=float(sim.wind_speed_m_s[j]),
            wind_direction_deg=sim.wind_direction_deg,
            sigma2=sigma2,
            outer_scale_m=scale,
            realisations=n_real,
            n_scans=n_max,
            min_peak_velocity=sim.min_peak_velocity_m_s,
        )
        stats = cumulative_vad_statistics(vd, valid, model.design, sim.max_lag)
        w_sum = np.cumsum(np.sum(np.where(valid, width2, 0.0), axis=-1), axis=1)
        est = estimate_parameters(stats, w_sum / stats["n_valid"], model)
        out["eps"][:, j] = relative_rms_error(est["epsilon"], eps)
        out["var"][:, j] = relative_rms_error(est["variance"], sigma2)
        out["scale"][:, j] = relative_rms_error(est["integral_scale"], scale)
        out["ratio"][:, j] = np.mean(est["epsilon"], axis=0) / eps
        out["n_valid"][:, j] = np.mean(stats["n_valid"], axis=0) / np.arange(1, n_max + 1)
    return xr.Dataset(
        {
            "epsilon_rel_error": (("n_scans", "height"), out["eps"]),
            "variance_rel_error": (("n_scans", "height"), out["var"]),
            "integral_scale_rel_error": (("n_scans", "height"), out["scale"]),
            "epsilon_mean_ratio": (("n_scans", "height"), out["ratio"]),
            "rays_per_scan_used": (("n_scans", "height"), out["n_valid"]),
            "true_epsilon": (("height",), truth_eps),
            "true_velocity_variance": (("height",), np.asarray(sim.sigma_v_m_s) ** 2),
            "true_integral_scale": (("height",), np.asarray(sim.outer_scale_m, dtype=float)),
            "true_wind_speed": (("height",), np.asarray(sim.wind_speed_m_s, dtype=float)),
        },
        coords={"n_scans": np.arange(1, n_max + 1), "height": heights},
        attrs={
            "realisations": n_real,
            "seed": seed,
            "max_lag": sim.max_lag,
            "method": (
                "Monte Carlo of Banakh et al. (1999), eqs. 14-23: V_D by Cholesky of B_D "
                "(eq. 15, corrected Lorentzian Q_s cut at the lidar), spectral widths by "
                "FFT (eq. 23); least-squares fit of D_L(l), l = 1..max_lag, with the exact "
                "eq. 17 model; L_V = 1.33 sigma^3/eps (eq. 19)"
            ),
        },
    )


def relative_rms_error(estimate: np.ndarray, truth: float) -> np.ndarray:
    """[<(x^ - x)^2>]^(1/2) / x over realisations (axis 0), Banakh et al. (1999), Figs. 5-7."""
    return np.sqrt(np.nanmean((estimate - truth) ** 2, axis=0)) / truth


def format_table(study: xr.Dataset) -> str:
    """The study as a plain-text table (percent), one block per quantity."""
    n = study.attrs["realisations"]
    lines = [f"Monte-Carlo error study of Banakh et al. (1999) ({n} realisations)"]
    blocks = [
        ("epsilon_rel_error", "relative RMS error of epsilon (%)"),
        ("variance_rel_error", "relative RMS error of sigma_V^2 (%)"),
        ("integral_scale_rel_error", "relative RMS error of L_V (%)"),
        ("epsilon_mean_ratio", "mean eps^/eps (bias, %)"),
    ]
    heights = study["height"].values
    for name, title in blocks:
        lines.append("")
        lines.append(title)
        lines.append("  N " + "".join(f"{h:>8.0f}m" for h in heights))
        for i, n in enumerate(study["n_scans"].values):
            row = study[name].values[i] * 100.0
            lines.append(f"{n:>3d} " + "".join(f"{v:>9.1f}" for v in row))
    return "\n".join(lines)


def plot_study(study: xr.Dataset, path: str) -> None:
    """PNG of the three relative errors versus N, one curve per height (Figs. 5-7)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [
        ("epsilon_rel_error", r"$\sigma_\varepsilon$ (%)"),
        ("variance_rel_error", r"$\sigma_{\sigma_V^2}$ (%)"),
        ("integral_scale_rel_error", r"$\sigma_{L_V}$ (%)"),
    ]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), constrained_layout=True)
    n = study["n_scans"].values
    for ax, (name, label) in zip(axes, names, strict=True):
        for j, h in enumerate(study["height"].values):
            ax.plot(n, study[name].values[:, j] * 100.0, marker="o", label=f"{h:.0f} m")
        ax.set_xlabel("number of scans N")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(title="height")
    fig.suptitle(f"Banakh et al. (1999) Monte Carlo, {study.attrs['realisations']} realisations")
    fig.savefig(path, dpi=100)
    plt.close(fig)
