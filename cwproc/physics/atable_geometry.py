"""The pair geometry of the A-tables: eq.-15 azimuths, the exact two-beam corrections.

Smalikho (2020), eq. 15 takes two rays as parallel beams seen in the small-angle
limit. The tables correct it for the exact geometry of two tilted beams (their chord
and the angle between them, Banakh et al. (1999), eq. 16), as the ratio of the exact
point-probe pair to eq. 15 of the point (:func:`geometry_correction`), and add the
large-scale term of non-parallel beams (:func:`uniform_mode`). Used by
:func:`cwproc.physics.atable.build_a_table`.
"""

from __future__ import annotations

import math

import numpy as np

from cwproc.physics import afunctions, two_beam
from cwproc.physics.atable_interp import azimuth_nodes
from cwproc.physics.curve_kernel import CurveStack
from cwproc.physics.transfer import Probe

#: sub-beams of a swept ray in :func:`uniform_mode`
N_SWEEP = 8


def full_circle() -> np.ndarray:
    """Eq.-15 azimuths on the full circle: the half circle and its mirror ``pi - theta``.

    Smalikho (2020), eq. 15 depends on ``sin theta`` only; the exact two-beam geometry
    does not (with tilted beams a radial transport inwards and outwards differ), so the
    tables use both halves.
    """
    th = afunctions._theta()
    return np.concatenate([th, np.pi - th])


def _per_theta_a2(
    curves: afunctions.ACurves, lag_m: np.ndarray, mu: np.ndarray, phi_deg: float
) -> np.ndarray:
    """Integrand of Smalikho (2020), eq. 15 on :func:`full_circle`, ``(lags, mu, theta)``."""
    half = per_theta_half_a2(curves, lag_m, mu, phi_deg)
    return np.concatenate([half, half], axis=-1)  # eq. 15 is even in cos(theta)


def per_theta_half_a2(
    curves: afunctions.ACurves | CurveStack,
    lag_m: np.ndarray,
    mu: np.ndarray,
    phi_deg: float,
    points: tuple[np.ndarray, ...] | None = None,
) -> np.ndarray:
    """:func:`_per_theta_a2` on the half circle (the first half of :func:`full_circle`).

    ``points``: :func:`eq15_points` of ``(lag_m, mu, phi_deg)`` when already computed.
    """
    rho, log_rho, wp, wl = points or eq15_points(lag_m, mu, phi_deg)
    if isinstance(curves, CurveStack):
        return wp[None] * curves.perp(rho, log_rho) + wl[None] * curves.par(rho, log_rho)
    return wp[None] * curves.perp(rho) + wl[None] * curves.par(rho)


def eq15_points(
    lag_m: np.ndarray, mu: np.ndarray, phi_deg: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(rho, log rho)`` ``(lags, mu, theta)`` and the weights ``w_perp``, ``w_par``
    ``(mu, theta)`` of Smalikho (2020), eq. 15 on the half circle."""
    sg, wp, wl = afunctions.transport_weights(mu, phi_deg)  # (nm, nth) on the half circle
    rho = lag_m[:, None, None] * sg[None]
    return rho, np.log(np.maximum(rho, 1e-300)), wp, wl


def circle_halves(a: np.ndarray) -> np.ndarray:
    """``a (..., theta)`` on :func:`full_circle` as ``(..., 2, theta / 2)``: its two halves
    (a view of a contiguous array, so that a half-circle term broadcasts over both)."""
    return a.reshape(*a.shape[:-1], 2, a.shape[-1] // 2)


def _point_pair(
    phi_deg: float, delta_theta_deg: float, lags: np.ndarray, mu: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    """Exact two-beam A of a point probe on the circle ``R' = 1``, ``(lags, mu, theta)``.

    Pair ``l`` steps apart centred on north, scanning clockwise (towards east): the wind's
    component along the scan is ``U sin th``, ``U = mu`` (``V_s = 1``), ray period
    ``t0 = dtheta``. A point has no same-beam term: ``D`` is the cross term alone.
    """
    step = math.radians(delta_theta_deg)
    point = two_beam.beam_quadrature(None, 1.0 / math.cos(math.radians(phi_deg)))
    half = 0.5 * lags[:, None, None] * delta_theta_deg
    wind = (
        np.stack([np.zeros_like(theta), np.cos(theta), np.sin(theta)], axis=-1)
        * np.asarray(mu, float)[:, None, None]
    )  # (nm, nth, 3)
    shape = (lags.size, np.size(mu), theta.size)
    t_ab = -lags[:, None, None] * step  # t_a - t_b, a the earlier ray
    return two_beam.cross_term(
        np.broadcast_to(-half, shape),
        np.broadcast_to(half, shape),
        phi_deg,
        point,
        separation_m=np.broadcast_to(wind, (*shape, 3)) * t_ab[..., None],
        model="inertial",
    )


def geometry_correction(
    phi_deg: float, delta_theta_deg: float, n_lags: int, mu: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Ratio of the exact two-beam to the small-angle A of a point probe (inertial).

    The pair of rays ``l`` steps apart (:func:`cwproc.physics.two_beam.cross_term`: chord
    separation, angle between the beams, transport ``U t`` with ``U = mu V_s``) against
    Smalikho (2020), eq. 15 for the same point probe (``A_perp = (8/3) rho^(2/3)``,
    ``A_par = 2 rho^(2/3)``), both without the sweep; the tables of pulsed probes take
    the plane A-function of the pairs instead (:func:`_swept_pairs`). For a point probe
    and the inertial model both scale as ``R'^(2/3)``, so the ratio is computed once on
    the circle ``R' = 1``
    (``V_s = 1``, ray period ``dtheta``). The probe's eq.-15 A-functions plus the
    same-beam term, times this ratio, minus the same-beam term, give the exact geometry
    up to the interplay of probe length and beam angle (within 0.6 % of
    :func:`cwproc.physics.two_beam.two_beam_structure_function` for 15 deg step-stare
    pulsed scans, tested).

    Returns
    -------
    (g1, g2) : numpy.ndarray
        ``(n_lags,)`` at ``mu = 0`` and ``(n_lags, mu, theta)`` on :func:`full_circle`.
    """
    mu = np.asarray(mu, float)
    if mu.ravel()[0] != 0.0:
        raise ValueError("the mu grid must start at 0 (A_1 is taken there)")
    step = math.radians(delta_theta_deg)
    lags = np.arange(1, n_lags + 1, dtype=float)
    exact = _point_pair(phi_deg, delta_theta_deg, lags, mu, full_circle())
    lo, hi = 0.02 * step, n_lags * step * (1.0 + float(np.max(mu))) * 1.01
    curves = afunctions.a_curve_splines(lo, hi, probe=None, dy=0.0)
    small = _per_theta_a2(curves, lags * step, mu, phi_deg)
    # without wind the pair is the same at every azimuth: method 1's A_1 (mu = 0)
    calm = exact[:, 0, :].mean(axis=-1)
    return calm / curves.perp(lags * step), exact / small


def uniform_mode(phi_deg: float, delta_theta_deg: float, n_lags: int, swept: bool) -> np.ndarray:
    """``|S_a - S_b|^2`` of rays ``l = 1..n_lags`` steps apart (sweep-averaged directions).

    Times ``sigma_V^2`` it is the large-scale part of the two-beam structure function
    (:mod:`cwproc.physics.two_beam`), absent from the small-angle model.
    """
    lags = np.arange(1, n_lags + 1, dtype=float)
    sweep = dict(sweep_deg=delta_theta_deg, n_sweep=N_SWEEP) if swept else {}
    sa = two_beam.mean_direction(np.zeros_like(lags), phi_deg, **sweep)
    sb = two_beam.mean_direction(lags * delta_theta_deg, phi_deg, **sweep)
    return np.sum((sa - sb) ** 2, axis=-1)


def azimuth_to_nodes(theta: np.ndarray) -> np.ndarray:
    """``(theta, N_BINS)``: periodic linear interpolation from ``theta`` (rad) to the nodes."""
    order = np.argsort(np.mod(theta, 2 * np.pi))
    th_sorted = np.mod(theta, 2 * np.pi)[order]
    eye = np.eye(theta.size)[order]
    return np.stack(
        [
            np.interp(azimuth_nodes(), th_sorted, eye[:, k], period=2 * np.pi)
            for k in range(theta.size)
        ]
    )


def pair_geometry_terms(
    probe: Probe,
    params: dict,
    ranges: np.ndarray,
    mu: np.ndarray,
    swept: bool,
    ratios: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(same, g1, g2, unif)`` of the exact pair geometry, or neutral with small angles.

    ``same``: twice the same-beam term per height
    (:func:`cwproc.physics.two_beam.same_beam_term`); ``g1``, ``g2``: the point-probe
    ratios of :func:`geometry_correction` (ones when not ``ratios``: the inertial tables
    of pairs do not use them); ``unif``: :func:`uniform_mode`.
    """
    phi, n_lags = params["phi_deg"], params["n_lags"]
    if params.get("geometry", "two_beam") != "two_beam":
        n_th = full_circle().size
        return (
            np.zeros(ranges.size),
            np.ones(n_lags),
            np.ones((n_lags, mu.size, n_th)),
            np.zeros(n_lags),
        )
    # the same-beam term S: the exact-geometry ratio acts on the cross term A + 2 S
    same = np.array(
        [2.0 * two_beam.same_beam_term(two_beam.beam_quadrature(probe, rng), phi) for rng in ranges]
    )
    if ratios:
        g1, g2 = geometry_correction(phi, params["delta_theta_deg"], n_lags, mu)
    else:  # not used (inertial tables of pairs)
        g1, g2 = np.ones(n_lags), np.ones((n_lags, mu.size, full_circle().size))
    return same, g1, g2, uniform_mode(phi, params["delta_theta_deg"], n_lags, swept)
