"""Azimuth dependence of ``A_2`` for VADs of few step-stare rays, from the two-beam model.

A full circle of ``M`` rays lacks ``l`` of its ``M`` pair positions at lag ``l`` (pairs
do not wrap from a scan's last ray to its first), so the mean of ``D(l)`` over the pairs
present differs from the circle mean where the wind makes ``D`` vary with azimuth
(Smalikho (2020), eq. 15: ``mu`` near 1). With 24 or more rays the A-tables' per-node
ratios correct this; with 12 rays (30 deg steps, lags 30 and 60 deg) they do not: at
``mu`` 1, 1 s dwell in a 2 s ray period, ``L_V`` 200 m, h 100 m, phi 35 deg, the table's
inertial node ratio at lag 2 spans -0.11 to 1.72 (the exact von Kármán pairs 0.46 to
1.25), and the sector ratio of the pairs present came out 1.17 x 1.44 = 1.69 where the
exact covariance of :mod:`cwproc.sim.exact_gaussian` gives 1.077 (58.3 against a circle
mean of 54.2 eps^(2/3)): the fit's lag-2 model 57 % high, eps 0.21 of the truth.

:func:`node_a2` computes ``A_2`` per azimuth node directly:
:func:`cwproc.physics.two_beam.dwell_structure_function` (Banakh et al. (1999), eqs.
15-16, the rays seen over their dwell in the field the wind carries, Smalikho (2020), eq.
3) for a pair ``l`` steps apart whose middle is at angle ``theta`` from the direction the
wind blows to (the convention of :func:`cwproc.physics.block_stats.pair_azimuth_weights`),
with point beams, and :func:`sector_a2` averages it over the pairs present less the
probe's inertial share. The A-table's finite-outer-scale circle mean is not used
for these scans: at 60 deg lags, ``mu`` 3, ``L_V`` 100 m it is 35 % above the direct
two-beam value (41.7 against 30.9 eps^(2/3)). :func:`dwell_loss_ratio` is the outer
scale's factor on the inertial variance a ray loses to the transport during its dwell.
Point beams make both scale-free (functions of ``R'/L_V``), tabulated once per ``mu``
node on :data:`X_GRID` for every height. Pure numpy.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from cwproc.physics import two_beam
from cwproc.physics.atable_interp import N_BINS, azimuth_nodes

#: azimuth step (deg) from which full circles of step-stare rays take :func:`node_ratio`
#: (fewer than 18 rays: those that get fewer than three lags within 60 deg); 24- and
#: 36-ray VADs keep the A-tables' node ratios
FEW_RAYS_STEP_DEG = 20.0
#: spacing of the ``mu`` nodes of :func:`node_ratio` (linear interpolation between them)
MU_STEP = 0.1
#: sub-rays per dwell of :func:`cwproc.physics.two_beam.dwell_structure_function`
N_DWELL = 6
#: sub-rays per dwell of :func:`dwell_loss_ratio`
N_DWELL_LOSS = 12


#: nodes of ``x = R'/L_V`` of the scale-free curves (log-log interpolation between them):
#: with point beams ``A_2 / R'^(2/3)`` and the dwell-loss ratio are functions of
#: ``x``, ``mu``, the step, the dwell and the elevation only, so one curve per ``mu``
#: node serves every height
X_GRID = np.geomspace(1e-3, 1e3, 49)


@functools.lru_cache(maxsize=512)
def _a2_curve(
    n_lags: int, step_deg: float, dwell: float, mu: float, phi_deg: float, model: str
) -> np.ndarray:
    """``(n_x, n_lags, N_BINS)``: ``A_2`` of point beams at ``R' = 1 m`` at each node of
    :data:`X_GRID` (one row for ``"inertial"``), at one ``mu`` node."""
    theta = azimuth_nodes()
    range_m = 1.0 / math.cos(math.radians(phi_deg))  # R' = 1 m
    speed = mu * math.radians(step_deg)  # U = mu V_s, V_s = dy / tau, tau = 1 s
    wind = speed * np.stack([np.zeros(N_BINS), np.cos(theta), np.sin(theta)], -1)[:, None, :]
    scales = [None] if model == "inertial" else (1.0 / X_GRID).tolist()
    out = np.empty((len(scales), n_lags, N_BINS))
    for k, outer in enumerate(scales):
        for li in range(n_lags):
            half = 0.5 * (li + 1) * step_deg
            out[k, li] = two_beam.dwell_structure_function(
                np.full(N_BINS, -half),
                np.full(N_BINS, half),
                phi_deg,
                range_m,
                dwell_s=dwell,
                n_dwell=N_DWELL if dwell > 0 else 1,
                time_separation_s=np.full(N_BINS, -(li + 1.0)),
                mean_wind=wind,
                model=model,
                outer_scale_m=outer,
            )
    return out


def _at_x(curve: np.ndarray, x: np.ndarray, log: bool) -> np.ndarray:
    """``curve`` (first axis on :data:`X_GRID`) at ``x``, linear in ``log x`` (and in
    ``log curve`` where ``log``); clipped to the grid's ends."""
    lx = np.clip(np.log(np.asarray(x, float)), math.log(X_GRID[0]), math.log(X_GRID[-1]))
    pos = (lx - math.log(X_GRID[0])) / math.log(X_GRID[1] / X_GRID[0])
    i = np.clip(np.floor(pos).astype(int), 0, X_GRID.size - 2)
    w = (pos - i).reshape(-1, *([1] * (curve.ndim - 1)))
    lo, hi = curve[i], curve[i + 1]
    if log:
        return np.exp((1.0 - w) * np.log(lo) + w * np.log(hi))
    return (1.0 - w) * lo + w * hi


def node_a2(
    n_lags: int,
    step_deg: float,
    dwell: float,
    mu: float,
    phi_deg: float,
    range_m: float,
    scales_m: np.ndarray,
    model: str,
) -> np.ndarray:
    """``(n_scales, n_lags, N_BINS)``: ``A_2`` (m^(2/3)) of a step-stare pair of point
    beams at each azimuth node, at the outer scales ``scales_m``.

    The pair: rays ``l dtheta`` apart (``step_deg``), ``l`` ray periods apart in time,
    each dwelling the fraction ``dwell`` of the ray period, the wind ``mu = U/V_s``
    (Smalikho (2020), eq. 3) blowing towards ``theta`` (the node) from the pair's middle
    azimuth; point beams at ``range_m`` and ``phi_deg``, ``model`` with ``L_V`` =
    ``scales_m`` (any value for ``"inertial"``). Linear in ``mu`` between nodes
    :data:`MU_STEP` apart, each computed once (about 0.05 s for 23 outer scales and 2
    lags).
    """
    m = max(float(mu), 0.0) / MU_STEP
    lo = math.floor(m)
    frac = m - lo
    args = (int(n_lags), round(float(step_deg), 4), round(float(dwell), 4))
    phi = round(float(phi_deg), 3)
    curve = _a2_curve(*args, round(lo * MU_STEP, 6), phi, model)
    if frac > 1e-9:
        high = _a2_curve(*args, round((lo + 1) * MU_STEP, 6), phi, model)
        curve = (1.0 - frac) * curve + frac * high
    radius = float(range_m) * math.cos(math.radians(phi_deg))
    scales = np.atleast_1d(np.asarray(scales_m, float))
    if model == "inertial":
        per_scale = np.broadcast_to(curve, (scales.size, *curve.shape[1:]))
    else:
        per_scale = _at_x(curve, radius / scales, log=True)
    return radius ** (2.0 / 3.0) * per_scale


def sector_a2(
    weights: np.ndarray,
    step_deg: float,
    dwell: float,
    mu: np.ndarray,
    phi_deg: float,
    range_m: np.ndarray,
    scales_m: np.ndarray,
    model: str,
    probe_circle: np.ndarray,
) -> np.ndarray:
    """``(cells, n_scales, n_lags)``: ``A_2`` of the pairs present, with the probe.

    ``sum_k w_k A_k`` of :func:`node_a2` (point beams) with the node weights ``weights``
    ``(cells, n_lags, N_BINS)`` of each lag's pairs
    (:func:`cwproc.physics.block_stats.pair_azimuth_weights`), less what the probe takes:
    the inertial circle mean of point beams less that of the probe-averaged pairs
    (``probe_circle``, ``(cells, n_lags)``, the inertial A-table, within 0.3 % of the
    direct two-beam average). The probe's share is a difference, not a factor: at
    separations far beyond the probe the averaging lowers ``D`` by twice the variance
    it removes, whatever the outer scale. Against the exact covariance of a 12-ray
    VAD (instantaneous rays, wind from 250 deg, h 100 m, phi 35 deg) the mean over the
    pairs present at lags 1 / 2 was within 0.5 / 0.1 % at ``mu`` 0 and 1 (``L_V`` 200
    m) and -0.5 / -0.6 % at ``mu`` 3 (``L_V`` 100 m; the factor instead: -2 to -7 %,
    and the A-table's finite-outer-scale circle mean +35 % at lag 2 there). ``mu``,
    ``range_m``: ``(cells,)``. NaN where the inputs are not finite.
    """
    n_lags = weights.shape[1]
    out = np.full((weights.shape[0], np.size(scales_m), n_lags), np.nan)
    for c in range(weights.shape[0]):
        if not (np.isfinite(mu[c]) and np.isfinite(range_m[c])):
            continue
        a = node_a2(n_lags, step_deg, dwell, mu[c], phi_deg, range_m[c], scales_m, model)
        point = node_a2(n_lags, step_deg, dwell, mu[c], phi_deg, range_m[c], [1.0], "inertial")
        w = weights[c]
        known = np.all(np.isfinite(w), axis=-1)
        mean = np.einsum("sln,ln->sl", a, np.where(np.isfinite(w), w, 0.0))
        mean = np.where(known[None, :], mean, a.mean(axis=-1))
        out[c] = mean - (point[0].mean(axis=-1) - probe_circle[c])[None, :]
    return out


@functools.lru_cache(maxsize=256)
def _dwell_loss_curve(
    step_deg: float, dwell: float, mu: float, phi_deg: float, model: str
) -> np.ndarray:
    """``(n_x,)`` :func:`dwell_loss_ratio` on :data:`X_GRID` at one ``mu`` node."""
    theta = azimuth_nodes()
    speed = mu * math.radians(step_deg)  # R' = 1 m, tau = 1 s
    offsets = (np.arange(N_DWELL_LOSS) + 0.5) / N_DWELL_LOSS * dwell
    lag = (offsets[:, None] - offsets[None, :]).ravel()
    # beams at every node azimuth, the wind towards north: (node, sub-pair, 3)
    shift = speed * lag[None, :, None] * np.array([0.0, 1.0, 0.0])[None, None, :]
    shift = np.broadcast_to(shift, (N_BINS, lag.size, 3))
    az = np.broadcast_to(np.degrees(theta)[:, None], (N_BINS, lag.size))
    point = two_beam.beam_quadrature(None, 1.0 / math.cos(math.radians(phi_deg)))

    def loss(name: str, outer: float | None) -> float:
        c = two_beam.cross_term(
            az, az, phi_deg, point, separation_m=shift, model=name, outer_scale_m=outer
        )
        return 0.5 * float(np.mean(c))

    inertial = loss("inertial", None)
    if inertial <= 0:
        return np.ones(X_GRID.size)
    return np.array([loss(model, 1.0 / x) for x in X_GRID]) / inertial


def dwell_loss_ratio(
    step_deg: float,
    dwell: float,
    mu: float,
    phi_deg: float,
    range_m: float,
    scales_m: np.ndarray,
    model: str,
) -> np.ndarray:
    """``(n_scales,)``: the variance a step-stare ray loses to the transport during its
    dwell with the outer scale ``scales_m``, over the inertial loss.

    ``(1/2) mean_jk D_rr(U (o_j - o_k))`` of point beams (the own-average term of
    :func:`cwproc.physics.two_beam.dwell_structure_function`), ``D_rr`` the structure
    function along the beam, averaged over the beam's azimuth from the wind; ``U = mu
    dy / tau``. The inertial loss grows as the segment ``d mu dy`` to the 2/3 power
    without bound; with ``L_V`` 200 m and a 168 m segment (12 rays, 3 s dwell in 4 s,
    ``mu`` 3) it overstated the loss so that the passed share of sigma_V^2 was 5.7 %
    below the exact covariance's (0.596 against 0.632) and eps at the exact expected
    statistics 0.87. Linear in ``mu`` between nodes :data:`MU_STEP` apart.
    """
    if model == "inertial":
        return np.ones(np.size(scales_m))
    m = max(float(mu), 0.0) / MU_STEP
    lo = math.floor(m)
    frac = m - lo
    args = (round(float(step_deg), 4), round(float(dwell), 4))
    phi = round(float(phi_deg), 3)
    curve = _dwell_loss_curve(*args, round(lo * MU_STEP, 6), phi, model)
    if frac > 1e-9:
        high = _dwell_loss_curve(*args, round((lo + 1) * MU_STEP, 6), phi, model)
        curve = (1.0 - frac) * curve + frac * high
    radius = float(range_m) * math.cos(math.radians(phi_deg))
    return _at_x(curve, radius / np.atleast_1d(np.asarray(scales_m, float)), log=False)
