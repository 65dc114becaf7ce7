"""Variance of the probe-averaged radial velocity (Smalikho (2020), eqs. 16-20).

The probe volume (transfer functions ``H_par``, ``H_perp`` of Smalikho (2020), eqs.
19-20) passes part of sigma_V^2: :func:`passed_variance` integrates the 2-D spectrum of
a finite-outer-scale model times ``H_par H_perp``, :func:`averaging_loss` the inertial
spectrum (eq. 18) times ``1 - H_par H_perp``. Both per ``eps^(2/3)`` (m^(2/3)).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cwproc.physics import spectra
from cwproc.physics.transfer import transverse


def averaging_loss(
    probe: Any, dy: np.ndarray, range_m: np.ndarray, n_angle: int = 48, n_radius: int = 320
) -> np.ndarray:
    """Variance lost to the probe-volume averaging, per eps^(2/3) (m^(2/3)).

    ``int_0^inf int_0^inf Phi(k1, k2) [1 - H_par(k1) H_perp(k2)] dk1 dk2`` with the
    inertial 2-D spectrum of Smalikho (2020), eq. 18 and the transfer functions of eqs.
    19-20 (the quadrant integral of ``Phi`` is the variance: ``A = 2 int int Phi
    (1 - cos)``, eqs. 16-17). Polar quadrature, log-spaced in the radius, with the
    analytic ``rho^(-2/3)`` tail above 1000 cycles m-1.

    Parameters
    ----------
    probe : PulsedProbe or CWProbe
        ``probe.longitudinal(kappa, range_m)`` gives H_par.
    dy : numpy.ndarray
        Transverse sampling (m).
    range_m : numpy.ndarray
        Distance of the probe from the lidar (m), same shape as ``dy``.
    """
    dy = np.asarray(dy, dtype=float)
    shape = dy.shape
    dy_f = dy.ravel()[:, None, None]
    rng_f = np.broadcast_to(np.asarray(range_m, dtype=float), shape).ravel()[:, None, None]
    alpha = (np.arange(n_angle) + 0.5) * (np.pi / 2) / n_angle
    t = np.linspace(np.log(1e-6), np.log(1e3), n_radius)
    rho = np.exp(t)[None, None, :]
    ca, sa = np.cos(alpha)[None, :, None], np.sin(alpha)[None, :, None]
    c = spectra.exact_plane_constant()
    angular = c * (1 + (8 / 3) * sa**2)
    out = np.empty(dy_f.shape[0])
    chunk = max(1, 2_000_000 // (n_angle * n_radius))
    for i in range(0, dy_f.shape[0], chunk):  # memory-bounded chunks, each vectorised
        h = probe.longitudinal(rho * ca, rng_f[i : i + chunk]) * transverse(
            rho * sa, probe.transverse_size(dy_f[i : i + chunk])
        )
        f = angular * rho ** (-2 / 3) * (1 - h)
        radial = np.trapezoid(f, t, axis=-1)
        out[i : i + chunk] = radial.sum(axis=-1) * (np.pi / 2) / n_angle
    tail = 1.5 * 1e3 ** (-2 / 3) * c * (np.pi / 2) * (1 + (8 / 3) * 0.5)
    return (out + tail).reshape(shape)


def passed_variance(
    probe: Any,
    dy: np.ndarray,
    range_m: np.ndarray,
    model: str,
    outer_scales_m: np.ndarray,
    n_angle: int = 48,
    n_radius: int = 320,
) -> np.ndarray:
    """Variance of the probe-averaged radial velocity per eps^(2/3) (m^(2/3)).

    ``int_0^inf int_0^inf Phi_L(k1, k2) H_par(k1) H_perp(k2) dk1 dk2`` with the 2-D
    spectrum ``Phi_L = 4 [I1(kappa) - k1^2 I2(kappa)]`` of a finite-outer-scale model
    (:func:`cwproc.physics.spectra.plane_spectrum`) and the transfer functions of
    Smalikho (2020), eqs. 19-20: the limit of ``A/2`` at large separations (eqs. 16-17),
    so that the measured variance of ``V'_L`` is ``eps^(2/3)`` times this. Without the
    probe (``H = 1``) it equals ``sigma_V^2 / eps^(2/3)`` of the model (Banakh et al.
    (1999), eq. 19). ``I1`` and ``I2`` depend on ``|kappa|`` only, so the angular
    integrals of ``H`` and ``cos^2 H`` are done once per cell and combined with the
    spectrum of every outer scale by one matrix product.

    Parameters
    ----------
    probe : PulsedProbe or CWProbe
        ``probe.longitudinal(kappa, range_m)`` gives H_par.
    dy : numpy.ndarray
        Transverse sampling (m), 1-D (cells).
    range_m : numpy.ndarray
        Distance of the probe from the lidar (m), same shape as ``dy``.
    model : {"von_karman", "exponential"}
    outer_scales_m : numpy.ndarray
        L_V (m), 1-D.

    Returns
    -------
    numpy.ndarray
        Shape ``(cells, outer scales)``.
    """
    dy_f = np.asarray(dy, dtype=float).ravel()[:, None, None]
    rng_f = np.broadcast_to(np.asarray(range_m, dtype=float).ravel(), (dy_f.shape[0],))
    rng_f = rng_f[:, None, None]
    alpha = (np.arange(n_angle) + 0.5) * (np.pi / 2) / n_angle
    t = np.linspace(np.log(1e-6), np.log(1e3), n_radius)
    rho = np.exp(t)
    ca, sa = np.cos(alpha)[None, :, None], np.sin(alpha)[None, :, None]
    s0 = np.empty((dy_f.shape[0], n_radius))
    s2 = np.empty((dy_f.shape[0], n_radius))
    chunk = max(1, 2_000_000 // (n_angle * n_radius))
    for i in range(0, dy_f.shape[0], chunk):  # memory-bounded chunks, each vectorised
        r = rho[None, None, :]
        h = probe.longitudinal(r * ca, rng_f[i : i + chunk]) * transverse(
            r * sa, probe.transverse_size(dy_f[i : i + chunk])
        )
        s0[i : i + chunk] = h.sum(axis=1) * (np.pi / 2) / n_angle
        s2[i : i + chunk] = (h * ca**2).sum(axis=1) * (np.pi / 2) / n_angle
    w = np.gradient(t)  # trapezoid weights in log radius (end halves below)
    w[0] *= 0.5
    w[-1] *= 0.5
    out = np.empty((dy_f.shape[0], np.size(outer_scales_m)))
    for k, big_l in enumerate(np.atleast_1d(outer_scales_m)):
        across = spectra.plane_spectrum(0.0, rho, model, float(big_l))  # 4 I1
        along = spectra.plane_spectrum(rho, 0.0, model, float(big_l))  # 4 (I1 - rho^2 I2)
        out[:, k] = (s0 * across - s2 * (across - along)) @ (rho**2 * w)
    return out


def _segments(
    dy: float, mu: np.ndarray, phi_deg: float, dwell: float, swept: bool, n_theta: int
) -> tuple[np.ndarray, np.ndarray]:
    """Components ``(s1, s2)`` (m) along and across the beam of a ray's segment, ``(mu, theta)``.

    A swept ray averages the frozen field along ``dy (e_scan - mu e_wind)``, a step-stare
    ray of dwell fraction ``d`` along ``d mu dy e_wind``: across the horizontal beam ``dy (1
    - mu sin th)`` (swept) or ``d mu dy sin th``, along it ``mu dy cos th`` (or ``d`` times
    that), of which ``cos phi`` is along the beam and ``sin phi`` across it
    (:func:`cwproc.physics.atable_swept.swept_a2`). ``th`` on the Gauss-Chebyshev nodes
    of ``sin th`` (equal weights: the mean over the circle).
    """
    s = np.cos((np.arange(n_theta) + 0.5) * np.pi / n_theta)[None, :]  # sin(theta)
    mu = np.asarray(mu, float)[:, None]
    scale = dy if swept else dy * dwell
    across = dy * (1.0 - mu * s) if swept else scale * mu * s
    along_h = scale * mu * np.sqrt(1.0 - s * s)
    cphi, sphi = np.cos(np.radians(phi_deg)), np.sin(np.radians(phi_deg))
    return along_h * cphi, np.hypot(across, along_h * sphi)


def segment_loss(
    probe: Any,
    dy: np.ndarray,
    range_m: np.ndarray,
    mu: np.ndarray,
    *,
    phi_deg: float,
    swept: bool,
    dwell: float = 0.0,
    n_along: int = 42,
    n_across: int = 64,
    n_theta: int = 6,
) -> np.ndarray:
    """Variance a ray loses to the transport during its accumulation, per eps^(2/3) (m^(2/3)).

    A ray averages the field the mean wind carries past while it accumulates: a swept
    ray over the segment ``dy (e_scan - mu e_wind)`` (not the transverse ``dy`` of Smalikho
    (2020), eq. 20 alone), a step-stare ray of dwell fraction ``d`` over ``d mu dy e_wind``
    (:func:`_segments`). The filter of a uniform average over a segment ``(s1, s2)`` is
    ``sinc^2(pi (k1 s1 + k2 s2))``, here symmetrised in ``k2`` for the quadrant; the loss
    beyond the sweep's (``sinc^2(pi k2 dy)``, or none for step-stare) is

    ``int int Phi(k1, k2) H_par(k1) [H_0(k2) - F(k1, k2)] dk1 dk2``

    with the inertial spectrum of Smalikho (2020), eq. 18, ``Phi = C (1 + (8/3) k2^2 /
    k^2) k^(-8/3)`` (the segment is short against ``L_V``), averaged over the wind's
    azimuth to the scan. Zero at ``mu = 0``. Trapezoids in ``log k1`` (``1e-6 .. 1``
    cycles m-1: the pulsed ``H_par`` vanishes above) and ``log k2`` (``1e-6 .. 1e3``),
    ``n_along`` x ``n_across`` nodes: within 0.5 % of four times as many (Stream Line
    probe, 5-100 m steps, ``mu`` 0.5-6, swept and step-stare).

    Returns
    -------
    numpy.ndarray
        ``(cells, mu)``: ``dy`` and ``range_m`` are 1-D (cells), ``mu`` 1-D.
    """
    dy = np.atleast_1d(np.asarray(dy, dtype=float))
    rng = np.broadcast_to(np.asarray(range_m, dtype=float), dy.shape)
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    t1 = np.linspace(np.log(1e-6), 0.0, n_along)
    t2 = np.linspace(np.log(1e-6), np.log(1e3), n_across)
    k1, k2 = (g.ravel() for g in np.meshgrid(np.exp(t1), np.exp(t2), indexing="ij"))
    w1, w2 = np.gradient(t1), np.gradient(t2)
    w1[[0, -1]] *= 0.5
    w2[[0, -1]] *= 0.5
    rho2 = k1 * k1 + k2 * k2
    spectrum = spectra.exact_plane_constant() * (1 + (8 / 3) * k2 * k2 / rho2) * rho2 ** (-4 / 3)
    weight = spectrum * k1 * k2 * np.outer(w1, w2).ravel()
    out = np.zeros((dy.size, mu.size))
    for i in range(dy.size):
        h_par = probe.longitudinal(k1, rng[i])
        base = transverse(k2, probe.transverse_size(dy[i])) if swept else 1.0
        s1, s2 = _segments(float(dy[i]), mu, phi_deg, dwell, swept, n_theta)  # (mu, theta)
        along = s1[..., None] * k1
        across = s2[..., None] * k2
        f = (np.sinc(along + across) ** 2 + np.sinc(along - across) ** 2).mean(axis=1) * 0.5
        out[i] = (base - f) @ (weight * h_par)
    return out
