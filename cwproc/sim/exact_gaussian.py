"""Exact-statistics virtual lidar: Gaussian radial velocities with their exact covariance.

The gridded virtual lidar (:mod:`cwproc.sim.pulsed`) samples one realisation of a
periodic field whose smallest eddies are missing below two grid spacings, so it cannot
tell a retrieval bias of a few per cent from the missing small-scale energy. This module
draws the probe-averaged radial velocities of a whole block of scans *directly* as a
Gaussian vector whose covariance is the exact one of the model turbulence: no grid, no
periodic box, many independent realisations.

For rays ``i`` and ``k`` (beam unit vectors ``S_i``, ``S_k``, times ``t_i``, ``t_k``)
the covariance of the probe-averaged radial velocities is Banakh et al. (1999), eq. 15,

.. math::

    B_D(i, k) = \\iint Q(s) Q(s') S_i^T B(r) S_k \\, ds\\, ds',
    \\quad r = (R + s) S_i - (R + s') S_k - U (t_i - t_k),

with the isotropic correlation tensor ``B`` of Banakh et al. (1999), eq. 16, the pulsed
range weighting ``Q`` (:func:`cwproc.sim.pulsed.pulsed_range_weight`) and the transport
of the frozen field by the mean wind ``U`` (Taylor's hypothesis, Smalikho (2020), eq. 7).
A ray of a continuous scan also averages across the azimuths its beam sweeps while the
spectra accumulate (Smalikho (2020), eq. 20): the covariance of two such rays is the
average over pairs of point beams spread over the two rays' dwells, each at its own time
(:func:`sweep_offsets`). A step-stare ray holds its azimuth while it accumulates its
pulses, for ``T_d`` = pulses per ray / PRF (:attr:`ScanPattern.stare_s`), and the wind
carries the field past meanwhile: its point beams share the ray's azimuth and spread
over ``T_d`` in time (the same double average). To keep the small
differences between neighbouring rays accurate, the tensor is written through the
structure functions, ``B_ab(r) = sigma_V^2 delta_ab - D_ab(r)/2`` with
``D_ab = D_perp delta_ab + (D_par - D_perp) r_a r_b / r^2``:

.. math::

    B_D(i, k) = \\sigma_V^2 \\bar S_i \\cdot \\bar S_k - \\tfrac12 \\iint Q Q
        [D_\\perp S_i\\cdot S_k + (D_\\parallel - D_\\perp)(S_i\\cdot\\hat r)(S_k\\cdot\\hat r)],

so quadrature errors are relative to ``D`` (which vanishes at ``r = 0``), not to
``sigma_V^2``. ``D_par`` and ``D_perp`` are those of the von Kármán spectrum or of the
model of Banakh et al. (1999), eq. 17 (:mod:`cwproc.physics.spectra`).

The scans of a block repeat one pattern (azimuths and times within the scan) every
``scan_period_s``, so ``B_D`` is block-Toeplitz in the scan index and only the pairs
``(m, m', n - n')`` are computed. The quadrature step grows with the separation of the
two probe volumes (1 m when they are closer than about three probe lengths), so the
covariance of a 10-scan block of 180 rays takes seconds.

Without transport (``U = 0``) a frozen field would repeat itself exactly from scan to
scan; real turbulence decorrelates over a scan period, so there the scans are drawn
independently (``B_D`` block-diagonal) — the no-transport limit of Smalikho (2020).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from cwproc.physics import noise, spectra
from cwproc.physics.constants import STREAMLINE_DELTA_P_M, STREAMLINE_DELTA_R_M
from cwproc.physics.geometry import beam_unit_vector
from cwproc.physics.probe_lengths import FALLBACK_PRF_HZ as STREAMLINE_PRF_HZ

__all__ = [
    "ScanPattern",
    "block_covariance",
    "conical_pattern",
    "covariance_factor",
    "gaussian_scans",
    "structure_functions",
]
from cwproc.physics.geometry import wind_components
from cwproc.sim.pulsed import pulsed_range_weight, streamline_scans

#: half extent of the range weighting used, in units of Delta_p beyond Delta_R/2
_TAIL_PULSES = 3.0
#: quadrature step (m), largest centre separation (m) it is used for (the same ray: 0.5 m),
#: and whether the sweep of a continuous-scan ray is always resolved (beyond 100 m only
#: where the separation is below 20 arcs of the sweep, see block_covariance)
_STEPS_M = (
    (0.5, 0.0, True),
    (1.5, 30.0, True),
    (2.5, 100.0, True),
    (4.0, 250.0, False),
    (12.0, np.inf, False),
)
#: pulses per ray of the simulated Stream Line header (streamline_scans)
STREAMLINE_PULSES_PER_RAY = 10000
#: the sweep offsets (Delta, m) of a ray represented by its centre
_POINT = (np.zeros(1), np.zeros(1))
#: size of the separation table of D_par, D_perp (log-spaced, m)
_TABLE = (1e-4, 1e6, 6000)
#: field points per vectorised chunk (memory bound)
_CHUNK = 4_000_000


@dataclass(frozen=True)
class ScanPattern:
    """One scan of a block: ray azimuths and times, repeated every ``period_s``.

    Attributes
    ----------
    azimuth_deg : tuple of float
        Azimuth of the centre of each ray, clockwise from north (deg).
    time_s : tuple of float
        Time of the centre of each ray from the start of the scan (s).
    sweep_deg : float
        Azimuth swept by the beam during one ray (0 for a step-stare VAD) (deg).
    dwell_s : float
        Ray period: time from one ray to the next (s); a swept ray accumulates over all
        of it.
    period_s : float
        Time between the starts of consecutive scans (s).
    stare_s : float
        Step-stare rays: the time the beam holds each azimuth while the pulses accumulate,
        pulses per ray / PRF (s), centred on ``time_s``; 0: instantaneous rays.
    pulses_per_ray : int
        Pulses accumulated per ray (the Stream Line header's ``Pulses/ray``).
    """

    azimuth_deg: tuple[float, ...]
    time_s: tuple[float, ...]
    sweep_deg: float
    dwell_s: float
    period_s: float
    stare_s: float = 0.0
    pulses_per_ray: int = STREAMLINE_PULSES_PER_RAY

    @property
    def n_rays(self) -> int:
        return len(self.azimuth_deg)

    @property
    def averaged(self) -> bool:
        """Whether a ray averages over point beams (swept, or a stare with a dwell)."""
        return self.sweep_deg > 0 or self.stare_s > 0

    @property
    def accumulation_s(self) -> float:
        """Time over which a ray's point beams are spread (s): sweep or stare dwell."""
        return self.dwell_s if self.sweep_deg > 0 else self.stare_s


def conical_pattern(
    rays_per_scan: int,
    scan_period_s: float,
    *,
    sector_deg: float = 360.0,
    start_azimuth_deg: float = 0.0,
    gap: tuple[float, float] | None = None,
    continuous: bool = True,
    return_s: float = 0.0,
    pulses_per_ray: int | None = None,
    prf_hz: float = STREAMLINE_PRF_HZ,
) -> ScanPattern:
    """Pattern of a conical (PPI) scan: full circle, sector, or circle with a gap.

    Parameters
    ----------
    rays_per_scan : int
        Rays per scan M; the azimuth step is ``sector_deg / M`` (deg).
    scan_period_s : float
        Time the beam takes over the sector (s); rays are ``scan_period_s / M`` long.
    sector_deg : float
        Width of the scanned sector (deg); 360 for a full VAD/PPI circle.
    start_azimuth_deg : float
        Azimuth of the start of the sector (deg).
    gap : (float, float), optional
        ``(start_deg, width_deg)`` of an azimuth sector whose rays are missing (e.g.
        blocked by a building); the times of the remaining rays are unchanged.
    continuous : bool
        ``True``: the beam moves during each ray (continuous scan, transverse averaging
        over the step); ``False``: step-stare, the beam is fixed during the ray.
    return_s : float
        Time between the end of a scan and the start of the next (sector scans that
        fly back) (s).
    pulses_per_ray : int, optional
        Pulses per ray. Step-stare: each ray dwells ``pulses_per_ray / prf_hz`` at its
        azimuth (the rest of its ``scan_period_s / M`` the beam moves to the next);
        ``None``: instantaneous rays (the Stream Line's 10000 pulses in the header).
        Continuous scans accumulate over the whole ray whatever the pulses.
    prf_hz : float
        Pulse repetition frequency (Hz), the Stream Line's 15 kHz.
    """
    if rays_per_scan < 3 or not scan_period_s > 0 or not 0 < sector_deg <= 360:
        raise ValueError("rays_per_scan >= 3, scan_period_s > 0, 0 < sector_deg <= 360 needed")
    step = sector_deg / rays_per_scan
    dwell = scan_period_s / rays_per_scan
    stare = 0.0
    if pulses_per_ray is not None and not continuous:
        stare = pulses_per_ray / prf_hz
        if not 0 < stare <= dwell * (1 + 1e-9):
            raise ValueError(
                f"a dwell of {pulses_per_ray} pulses at {prf_hz:g} Hz ({stare:g} s) does not "
                f"fit the ray period of {dwell:g} s"
            )
    centre = (np.arange(rays_per_scan) + 0.5) * step
    azimuth = (start_azimuth_deg + centre) % 360.0
    time = (np.arange(rays_per_scan) + 0.5) * dwell
    if gap is not None:
        offset = (azimuth - gap[0]) % 360.0
        keep = offset >= gap[1]
        azimuth, time = azimuth[keep], time[keep]
    return ScanPattern(
        azimuth_deg=tuple(float(a) for a in azimuth),
        time_s=tuple(float(t) for t in time),
        sweep_deg=step if continuous else 0.0,
        dwell_s=dwell,
        period_s=scan_period_s + return_s,
        stare_s=stare,
        pulses_per_ray=STREAMLINE_PULSES_PER_RAY if pulses_per_ray is None else int(pulses_per_ray),
    )


@functools.lru_cache(maxsize=16)
def _structure_table(model: str, outer_scale_m: float) -> tuple[np.ndarray, ...]:
    """ln r and ln D_par, ln D_perp per eps^(2/3) on a log grid (for fast interpolation)."""
    r = np.geomspace(_TABLE[0], _TABLE[1], _TABLE[2])
    d_par = spectra.longitudinal_structure_function(r, model, outer_scale_m)
    d_perp = spectra.transverse_structure_function(r, model, outer_scale_m)
    return np.log(r), np.log(d_par), np.log(d_perp)


def structure_functions(
    r: np.ndarray, model: str, outer_scale_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """``D_par(r)``, ``D_perp(r)`` per ``eps^(2/3)`` (m^(2/3)) by log-log interpolation.

    The tables of :func:`cwproc.physics.spectra.longitudinal_structure_function` and
    :func:`~cwproc.physics.spectra.transverse_structure_function` (relative error of the
    interpolation below 1e-5); below the table ``D ~ r^(2/3)`` (inertial range).
    """
    ln_r, ln_par, ln_perp = _structure_table(model, float(outer_scale_m))
    x = np.log(np.maximum(r, 1e-300))
    below = x < ln_r[0]
    par = np.exp(np.interp(x, ln_r, ln_par) + np.where(below, (x - ln_r[0]) * 2 / 3, 0.0))
    perp = np.exp(np.interp(x, ln_r, ln_perp) + np.where(below, (x - ln_r[0]) * 2 / 3, 0.0))
    zero = r <= 0
    return np.where(zero, 0.0, par), np.where(zero, 0.0, perp)


def pulse_range_nodes(delta_p_m: float, delta_r_m: float, step_m: float) -> tuple[np.ndarray, ...]:
    """Nodes (m from the gate centre) and weights (sum 1) of the pulsed range weighting.

    Midpoint rule on ``Q(s)`` of :func:`cwproc.sim.pulsed.pulsed_range_weight`, out to
    ``3 Delta_p`` beyond the range window.
    """
    half = delta_r_m / 2 + _TAIL_PULSES * delta_p_m
    n = int(np.ceil(half / step_m))
    s = (np.arange(-n, n + 1)) * step_m
    w = pulsed_range_weight(s, delta_p_m, delta_r_m)
    return s, w / w.sum()


def sweep_offsets(
    lag: int, n_nodes: int = 6, n_mean: int = 3
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes and weights of the double average over the sweeps of two rays.

    Two rays ``l`` azimuth steps apart, each averaging the beam uniformly over one step
    ``w`` (Smalikho (2020), eq. 20), see point beams at offsets ``u``, ``u'`` (in steps,
    uniform on [-1/2, 1/2]) from their centres. In ``Delta = u - u'`` (triangular
    density ``1 - |Delta|`` on [-1, 1]) and ``m = (u + u')/2`` (uniform on
    ``|m| <= (1 - |Delta|)/2``) the integrand is smooth in ``m`` and has the ``|x|^(2/3)``
    cusp of the structure function where the two point beams coincide, ``Delta = l``
    (inside or at an end of the interval for ``|l| <= 1``). Gauss-Legendre nodes on each
    half of ``Delta``, mapped by ``v^3`` towards such an end, and ``n_mean`` nodes in ``m``
    integrate it to about 1e-5.

    Returns
    -------
    delta, mean, weights : numpy.ndarray
        ``Delta`` and ``m`` (steps) and weights (sum 1), shape (2 n_nodes n_mean,).
    """
    x, w = np.polynomial.legendre.leggauss(n_nodes)
    v, wv = (x + 1) / 2, w / 2
    xm, wm = np.polynomial.legendre.leggauss(n_mean)
    deltas, weights = [], []
    for lo, hi in ((-1.0, 0.0), (0.0, 1.0)):
        cusp_lo, cusp_hi = lo == lag, hi == lag
        if cusp_lo and not cusp_hi:
            t, dt = v**3, 3 * v**2
        elif cusp_hi and not cusp_lo:
            t, dt = 1 - (1 - v) ** 3, 3 * (1 - v) ** 2
        else:
            t, dt = v, np.ones_like(v)
        delta = lo + (hi - lo) * t
        deltas.append(delta)
        weights.append(wv * dt * (hi - lo) * (1 - np.abs(delta)))
    delta_a, weight_a = np.concatenate(deltas), np.concatenate(weights)
    mean = np.outer((1 - np.abs(delta_a)) / 2, xm)
    weight = np.outer(weight_a, wm / 2)
    delta = np.repeat(delta_a[:, None], n_mean, axis=1)
    return delta.ravel(), mean.ravel(), weight.ravel() / weight.sum()


def _pair_structure(
    beams_i: np.ndarray,
    beams_k: np.ndarray,
    shift: np.ndarray,
    weight: np.ndarray,
    range_m: float,
    nodes: tuple[np.ndarray, np.ndarray],
    model: str,
    outer_scale_m: float,
) -> np.ndarray:
    """``(1/2) iint Q Q S_i^T D(r) S_k`` per eps^(2/3), averaged over point-beam pairs.

    ``beams_*`` (P, J, 3) point beams of the J pairs standing for each ray pair,
    ``shift`` (P, J, 3) their transport ``-U (t_i - t_k)``, ``weight`` (J,) the sweep
    weights. Returns (P,) (m^(2/3)).
    """
    s, w = nodes
    dist = range_m + s
    # r = dist_a S_i - dist_b S_k + shift, shape (P, J, n, n, 3)
    r = (
        dist[None, None, :, None, None] * beams_i[:, :, None, None, :]
        - dist[None, None, None, :, None] * beams_k[:, :, None, None, :]
        + shift[:, :, None, None, :]
    )
    rr = np.sqrt(np.einsum("...c,...c->...", r, r))
    d_par, d_perp = structure_functions(rr, model, outer_scale_m)
    safe = np.where(rr > 0, rr, 1.0)
    pi = np.einsum("pjc,pjabc->pjab", beams_i, r) / safe
    pk = np.einsum("pjc,pjabc->pjab", beams_k, r) / safe
    dot = np.einsum("pjc,pjc->pj", beams_i, beams_k)
    integrand = d_perp * dot[:, :, None, None] + (d_par - d_perp) * pi * pk
    return 0.5 * np.einsum("pjab,j,a,b->p", integrand, weight, w, w)


def _point_beams(
    pattern: ScanPattern,
    elevation_deg: float,
    ii: np.ndarray,
    kk: np.ndarray,
    offsets: tuple[np.ndarray, np.ndarray],
    scan_lag: int,
) -> tuple[np.ndarray, ...]:
    """Point beams (P, J, 3) of rays ``ii`` (scan n) and ``kk`` (scan n + scan_lag).

    ``offsets`` = (Delta, m) of :func:`sweep_offsets`: ray ``i`` at ``m + Delta/2``, ray
    ``k`` at ``m - Delta/2`` steps from its centre. Also returns ``t_i - t_k`` (P, J) (s).
    """
    delta, mean = offsets
    az = np.asarray(pattern.azimuth_deg)
    t = np.asarray(pattern.time_s)
    u_i = (mean + 0.5 * delta)[None, :]
    u_k = (mean - 0.5 * delta)[None, :]
    beams_i = beam_unit_vector(az[ii][:, None] + u_i * pattern.sweep_deg, elevation_deg)
    beams_k = beam_unit_vector(az[kk][:, None] + u_k * pattern.sweep_deg, elevation_deg)
    spread = pattern.accumulation_s
    dt = (t[ii] - t[kk])[:, None] + (u_i - u_k) * spread - scan_lag * pattern.period_s
    return beams_i, beams_k, dt


def _ray_lags(pattern: ScanPattern, ii: np.ndarray, kk: np.ndarray, scan_lag: int) -> np.ndarray:
    """Azimuth steps between rays ``ii`` and ``kk`` of one scan (``m + 2``: apart).

    The sweeps of two rays touch where ``|lag| <= 1``; a stare's point beams meet only
    within the same ray; rays of different scans never touch.
    """
    m = pattern.n_rays
    if scan_lag != 0:
        return np.full(ii.size, m + 2)
    if pattern.sweep_deg > 0:
        az = np.asarray(pattern.azimuth_deg)
        lags = np.rint(((az[kk] - az[ii] + 180.0) % 360.0 - 180.0) / pattern.sweep_deg)
        return lags.astype(int)
    if pattern.averaged:
        return np.where(ii == kk, 0, m + 2)
    return np.full(ii.size, m + 2)


def block_covariance(
    pattern: ScanPattern,
    n_scans: int,
    *,
    elevation_deg: float,
    range_m: float,
    epsilon: float,
    outer_scale_m: float,
    model: str = "von_karman",
    mean_wind: Sequence[float] = (0.0, 0.0, 0.0),
    delta_p_m: float = STREAMLINE_DELTA_P_M,
    delta_r_m: float = STREAMLINE_DELTA_R_M,
    sweep_nodes: int = 6,
) -> np.ndarray:
    """Covariance ``B_D`` of the probe-averaged radial velocities of a block of scans.

    Banakh et al. (1999), eqs. 15-16, in the structure-function form of the module
    docstring, with transport by ``mean_wind`` between all rays of the block.

    Parameters
    ----------
    pattern : ScanPattern
        Geometry of one scan (see :func:`conical_pattern`).
    n_scans : int
        Scans in the block (N).
    elevation_deg : float
        Elevation of the beams (deg).
    range_m : float
        Range of the gate centre along the beam (m).
    epsilon, outer_scale_m : float
        Dissipation rate (m2 s-3) and longitudinal integral scale L_V (m) of the field.
    model : {"von_karman", "exponential"}
        Correlation model of the field (:mod:`cwproc.physics.spectra`).
    mean_wind : sequence of float
        (u, v, w) (m s-1), eastward, northward, upward.
    delta_p_m, delta_r_m : float
        Pulse and range-window lengths of the range weighting (m), Smalikho (2020), eq. 19.
    sweep_nodes : int
        Gauss-Legendre nodes per half of the sweep average (:func:`sweep_offsets`).

    Returns
    -------
    numpy.ndarray
        ``(N M, N M)`` covariance (m2 s-2), rays ordered scan by scan.
    """
    if model not in ("von_karman", "exponential"):
        raise ValueError("the field needs a finite variance: model 'von_karman' or 'exponential'")
    wind = np.asarray(mean_wind, dtype=float)
    sigma2 = spectra.variance_per_eps23(model, outer_scale_m)  # per eps^(2/3)
    beams = _PairBeams(
        pattern,
        elevation_deg,
        range_m,
        wind,
        model,
        outer_scale_m,
        sweep_nodes,
        pulse=(delta_p_m, delta_r_m),
    )
    blocks: dict[int, np.ndarray] = {}
    for scan_lag in range(n_scans) if bool(np.any(wind != 0)) else range(1):
        mean_beam, value = _scan_lag_structure(beams, scan_lag)
        blocks[scan_lag] = sigma2 * (mean_beam @ mean_beam.T) - value
    return block_toeplitz(blocks, n_scans) * epsilon ** (2.0 / 3.0)


@dataclass(frozen=True)
class _PairBeams:
    """The settings of :func:`block_covariance` its pairs of rays are computed with."""

    pattern: ScanPattern
    elevation_deg: float
    range_m: float
    wind: np.ndarray
    model: str
    outer_scale_m: float
    sweep_nodes: int
    #: (delta_p_m, delta_r_m) of the range weighting (m)
    pulse: tuple[float, float]


def _scan_lag_structure(beams: _PairBeams, scan_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """``(mean beams (M, 3), D per eps^(2/3) (M, M))`` of the rays of one scan with those
    ``scan_lag`` scans later: the structure form of :func:`block_covariance` per pair,
    from the separation of the rays' mean beams at their centre times."""
    pattern, range_m, wind = beams.pattern, beams.range_m, beams.wind
    m = pattern.n_rays
    ii, kk = (a.ravel() for a in np.meshgrid(np.arange(m), np.arange(m), indexing="ij"))
    # the ray's mean beam (sweep average of the unit vectors) and the centre separation
    sweep = pattern.averaged
    delta, mean, weight = sweep_offsets(0, beams.sweep_nodes) if sweep else (*_POINT, np.ones(1))
    beams_i, _, _ = _point_beams(
        pattern, beams.elevation_deg, np.arange(m), np.arange(m), (delta, mean), 0
    )
    mean_beam = np.einsum("pjc,j->pc", beams_i, weight)
    dt_c = (np.asarray(pattern.time_s)[ii] - np.asarray(pattern.time_s)[kk]) - (
        scan_lag * pattern.period_s
    )
    sep = np.linalg.norm(range_m * (mean_beam[ii] - mean_beam[kk]) - wind * dt_c[:, None], axis=-1)
    lag_rays = _ray_lags(pattern, ii, kk, scan_lag)
    if scan_lag == 0:  # B_D(i, k) = B_D(k, i) within a scan: the upper triangle suffices
        sep = np.where(ii <= kk, sep, np.nan)
        # the same or touching rays: the r^(2/3) cusp where the point beams meet
        # needs the 0.5 m range step
        sep[(ii == kk) | ((np.abs(lag_rays) <= 1) & (ii <= kk))] = -1.0
    value = _pair_structures(beams, scan_lag, (ii, kk), mean_beam, sep, lag_rays)
    value = value.reshape(m, m)
    if scan_lag == 0:
        value = np.where(np.isnan(value), value.T, value)
    return mean_beam, value


def _pair_structures(
    beams: _PairBeams,
    scan_lag: int,
    pairs: tuple[np.ndarray, np.ndarray],
    mean_beam: np.ndarray,
    sep: np.ndarray,
    lag_rays: np.ndarray,
) -> np.ndarray:
    """D per eps^(2/3) of the ray pairs ``(ii, kk)`` (NaN where ``sep`` is NaN): range steps
    by the separation (:data:`_STEPS_M`), sweep and transport resolved where they are not
    small against it."""
    pattern, range_m, wind = beams.pattern, beams.range_m, beams.wind
    ii, kk = pairs
    value = np.full(ii.size, np.nan)
    lower = -np.inf
    # the sweep of a ray (its arc, m) and the transport during it matter where they
    # are not small against the separation; beyond 20 of them (and 100 m) the ray's
    # mean beam at its centre time stands for it
    arc = range_m * np.cos(np.deg2rad(beams.elevation_deg)) * np.deg2rad(pattern.sweep_deg)
    arc += float(np.linalg.norm(wind)) * pattern.accumulation_s
    for step, upper, sub in _STEPS_M:
        sel = np.flatnonzero((sep >= lower) & (sep < upper))
        lower = upper
        if sel.size == 0:
            continue
        nodes = pulse_range_nodes(*beams.pulse, step)
        # (not beyond 5 L_V, where the covariance has decayed: a stare's transport
        # in a strong wind would otherwise resolve every pair of the block)
        near = (sep[sel] < 20.0 * arc) & (sep[sel] < 5.0 * beams.outer_scale_m)
        use_sub = pattern.averaged & (sub | near)
        key = np.where(use_sub, lag_rays[sel], np.iinfo(np.int64).min)
        for lag in np.unique(key):
            grp = sel[key == lag]
            if lag != np.iinfo(np.int64).min:
                delta, mean, weight = sweep_offsets(int(lag), beams.sweep_nodes)
            else:
                delta, mean, weight = *_POINT, np.ones(1)
            per_pair = delta.size * nodes[0].size ** 2 * 3
            chunk = max(1, _CHUNK // per_pair)
            for c0 in range(0, grp.size, chunk):
                p = grp[c0 : c0 + chunk]
                bi, bk, dtp = _point_beams(
                    pattern, beams.elevation_deg, ii[p], kk[p], (delta, mean), scan_lag
                )
                if lag == np.iinfo(np.int64).min:  # the ray's mean beam, centre time
                    bi, bk = mean_beam[ii[p]][:, None, :], mean_beam[kk[p]][:, None, :]
                shift = -wind[None, None, :] * dtp[..., None]
                value[p] = _pair_structure(
                    bi, bk, shift, weight, range_m, nodes, beams.model, beams.outer_scale_m
                )
    return value


def block_toeplitz(blocks: dict[int, np.ndarray], n_scans: int) -> np.ndarray:
    """The symmetric ``(N M, N M)`` matrix of the scan-lag blocks of a stationary field.

    ``blocks[s]`` holds the covariance of the rays of scan ``n`` (rows) with those of scan
    ``n + s`` (columns); a frozen field without wind has only ``blocks[0]`` (scans
    uncorrelated at other lags give zero blocks).
    """
    m = next(iter(blocks.values())).shape[0]
    out = np.zeros((n_scans * m, n_scans * m))
    for a in range(n_scans):
        for b in range(n_scans):
            lag = b - a
            if lag in blocks:
                out[a * m : (a + 1) * m, b * m : (b + 1) * m] = blocks[lag]
            elif -lag in blocks:
                out[a * m : (a + 1) * m, b * m : (b + 1) * m] = blocks[-lag].T
    return 0.5 * (out + out.T)


def gaussian_scans(
    *,
    pattern: ScanPattern,
    n_scans: int,
    n_blocks: int,
    elevation_deg: float,
    ranges_m: Sequence[float],
    epsilon: float,
    outer_scale_m: float,
    wind_speed_m_s: float,
    wind_direction_deg: float,
    noise_std_m_s: float,
    seed: int,
    model: str = "von_karman",
    delta_p_m: float = STREAMLINE_DELTA_P_M,
    delta_r_m: float = STREAMLINE_DELTA_R_M,
    sweep_nodes: int = 6,
    snr: float | None = None,
    start_time: str = "2024-06-01T00:00:00",
    block_gap_s: float = 60.0,
    noise_factor: float = 1.0,
) -> xr.Dataset:
    """Independent blocks of scans with the exact covariance, as a canonical scan dataset.

    Each of the ``n_blocks`` blocks is an independent realisation of ``n_scans``
    consecutive scans (:func:`block_covariance`); gates are independent of each other
    (the estimates are made per gate). White noise of ``noise_std_m_s`` is added to every
    estimate (Smalikho (2020), eq. 4), and the mean wind projected on the beam.

    ``noise_factor``: the white noise drawn has ``noise_factor x noise_std_m_s``, while
    the SNR column (``snr`` None) still predicts ``noise_std_m_s`` (Pearson et al.
    (2009), eq. 3, :func:`cwproc.physics.noise.snr_for_noise_std`): a lidar whose noise
    the SNR misstates (a wrong spectral width, a degraded detector), the case where the
    noise must be decided by the structure function (Smalikho (2020), eq. 4).
    ``sim_noise_std`` is the noise drawn, ``sim_noise_std_predicted`` the one the SNR
    predicts.

    Returns
    -------
    xarray.Dataset
        Dims ``ray`` (n_blocks N M) and ``range``; the layout of
        :func:`cwproc.sim.pulsed.sample_conical_scans` with ``qc_flag_radial = 0``, so
        the stage chain runs on it unchanged. ``sim_*`` attributes hold the truth.
    """
    ranges = np.asarray(ranges_m, dtype=float)
    u, v = wind_components(wind_speed_m_s, wind_direction_deg)
    wind = np.array([u, v, 0.0])
    rng = np.random.default_rng(seed)
    velocity, worst = _gate_draws(
        pattern,
        (n_scans, n_blocks),
        ranges,
        rng,
        elevation_deg=elevation_deg,
        epsilon=epsilon,
        outer_scale_m=outer_scale_m,
        model=model,
        mean_wind=wind,
        delta_p_m=delta_p_m,
        delta_r_m=delta_r_m,
        sweep_nodes=sweep_nodes,
    )
    beams = beam_unit_vector(np.asarray(pattern.azimuth_deg), elevation_deg)
    velocity += np.tile(beams @ wind, n_scans)[None, :, None]
    drawn = float(noise_std_m_s) * float(noise_factor)
    velocity += drawn * rng.standard_normal(velocity.shape)
    times, azimuth, scan = _block_rays(pattern, n_scans, n_blocks, start_time, block_gap_s)
    n_rays = times.size
    ds = streamline_scans(
        velocity.reshape(n_rays, ranges.size),
        times=times,
        azimuth=azimuth,
        elevation_deg=elevation_deg,
        ranges_m=ranges,
        scan=scan,
        snr=snr,
        delta_p_m=delta_p_m,
        delta_r_m=delta_r_m,
        stepped=pattern.sweep_deg == 0,
        pulses_per_ray=pattern.pulses_per_ray,
        truth={
            **_field_truth(epsilon, outer_scale_m, model),
            "sim_noise_std": drawn,
            "sim_noise_std_predicted": float(noise_std_m_s),
            "sim_seed": int(seed),
            "sim_wind_speed": float(wind_speed_m_s),
            "sim_wind_direction_deg": float(wind_direction_deg),
            "sim_scan_period_s": float(pattern.period_s),
            "sim_covariance_clipped": worst,
            "sim_velocity_variance": float(spectra.variance_from(epsilon, outer_scale_m, model)),
        },
    )
    if snr is None:  # the SNR at which the file's settings predict noise_std_m_s
        ds["snr"][:] = _predicting_snr(ds.attrs, float(noise_std_m_s))
    ds["qc_flag_radial"] = (("ray", "range"), np.zeros((n_rays, ranges.size), np.int8))
    return ds


def _predicting_snr(attrs: dict, noise_std_m_s: float) -> float:
    """The SNR at which a Stream Line file of ``attrs`` predicts ``noise_std_m_s`` (m s-1;
    Pearson et al. (2009), eq. 3, :func:`cwproc.physics.noise.snr_for_noise_std`)."""
    return noise.snr_for_noise_std(
        noise_std_m_s,
        attrs["points_per_gate"],
        attrs["pulses_per_ray"],
        noise.bandwidth_from_resolution(attrs["velocity_resolution_m_s"]),
    )


def _field_truth(epsilon: float, outer_scale_m: float, model: str) -> dict[str, object]:
    """The ``sim_*`` attributes of the field: its generator, eps (m2 s-3), L_V (m) and
    correlation model."""
    return {
        "sim_generator": "exact Gaussian (cwproc.sim.exact_gaussian)",
        "sim_epsilon": float(epsilon),
        "sim_integral_scale_m": float(outer_scale_m),
        "sim_model": model,
    }


def _gate_draws(
    pattern: ScanPattern,
    counts: tuple[int, int],
    ranges: np.ndarray,
    rng: np.random.Generator,
    **covariance: object,
) -> tuple[np.ndarray, float]:
    """``(velocity (blocks, N M, gate), largest clipped eigenvalue)``: independent blocks
    of ``counts = (N scans, blocks)`` drawn gate by gate with :func:`block_covariance`
    (its keyword arguments ``covariance``) through :func:`covariance_factor`."""
    n_scans, n_blocks = counts
    n = n_scans * pattern.n_rays
    velocity = np.empty((n_blocks, n, ranges.size))
    worst = 0.0
    for g, range_m in enumerate(ranges):
        cov = block_covariance(pattern, n_scans, range_m=float(range_m), **covariance)
        factor, clipped = covariance_factor(cov)
        worst = max(worst, clipped)
        velocity[:, :, g] = rng.standard_normal((n_blocks, n)) @ factor.T
    return velocity, worst


def _block_rays(
    pattern: ScanPattern, n_scans: int, n_blocks: int, start_time: str, block_gap_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(times, azimuths (deg), scan numbers)`` of the rays of ``n_blocks`` blocks of
    ``n_scans`` scans, ``block_gap_s`` (s) between the blocks."""
    scan_t = np.arange(n_scans)[:, None] * pattern.period_s + np.asarray(pattern.time_s)
    block_len = n_scans * pattern.period_s + block_gap_s
    t = (np.arange(n_blocks)[:, None] * block_len + scan_t.ravel()[None, :]).ravel()
    times = np.datetime64(start_time, "ns") + np.round(t * 1e9).astype("timedelta64[ns]")
    azimuth = np.tile(np.asarray(pattern.azimuth_deg), n_blocks * n_scans)
    scan = np.repeat(np.arange(n_blocks * n_scans), pattern.n_rays).astype(np.int64)
    return times, azimuth, scan


def covariance_factor(cov: np.ndarray) -> tuple[np.ndarray, float]:
    """Factor ``F`` with ``F F^T`` the nearest positive semi-definite matrix to ``cov``.

    Neighbouring rays of a dense scan are so strongly correlated that the smallest
    eigenvalues of ``B_D`` are of the order of the quadrature error; those that come out
    negative are set to zero (the nearest PSD matrix in the Frobenius norm), and their
    largest magnitude relative to the mean variance is returned as a diagnostic.

    Returns
    -------
    factor : numpy.ndarray
        ``(n, n)`` (m s-1).
    clipped : float
        Largest negative eigenvalue removed, relative to ``mean(diag(cov))`` (0 if none).
    """
    lam, vec = np.linalg.eigh(cov)
    clipped = float(max(0.0, -lam.min()) / np.mean(np.diag(cov)))
    return vec * np.sqrt(np.clip(lam, 0.0, None)), clipped
