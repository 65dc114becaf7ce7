"""A-functions of the azimuth structure function of a conically scanning lidar.

The lidar azimuth structure function is ``D = eps^(2/3) A`` (Smalikho (2020), eqs. 4, 14);
``A`` (m^(2/3)) accounts for the averaging of the radial velocity over the probe volume.

- :func:`a_perp`, :func:`a_par`: Smalikho (2020), eqs. 16-17, the double integrals of the
  2-D spectrum (eq. 18, or a finite-outer-scale spectrum from :mod:`cwproc.physics.spectra`)
  with the longitudinal transfer function of the probe (eq. 19 or the cw Lorentzian,
  :mod:`cwproc.physics.transfer`) and the transverse one ``sinc^2(pi dy kappa2)`` (eq. 20).
- :func:`a2`: Smalikho (2020), eq. 15, the theta-average with wind transport
  (``mu = U / V_s``); the lag is ``l dy sqrt(g)``, ``g = (1 - mu sin th)^2 + (mu cos th)^2``
  (the extraction prints "dtheta"; it is ``dy``), ``H_perp`` keeps the fixed ``dy``.
- the ratio of the method-1 and method-2 estimates of eps built on them, Smalikho (2020),
  eqs. 21-23, is :mod:`cwproc.physics.epsilon_bias`.

Numerics. The double integrals are reduced to nested 1-D integrals: an inner integral of
the 2-D spectrum against one transfer function, then an outer oscillatory integral
against the other transfer function and ``1 - cos(2 pi r kappa)``. Both use the same
panels (geometric, ratio 1.5, from ``1e-5/s_max`` to ``2e3/s_min``, ``2e7/s_min`` when a
filter is absent; ``s`` are the lags and probe lengths) with 8 Gauss-Legendre
nodes each; on every panel the smooth factor is represented by its degree-7 Legendre
interpolant and its product with ``cos(2 pi w kappa)`` is integrated exactly (Filon-type
quadrature with the moments ``int P_m(x) exp(i a x) dx = 2 i^m j_m(a)``), so arbitrarily
large lags cost nothing extra. The oscillating ``sinc^2(pi l kappa) = (1 - cos(2 pi l
kappa)) / (2 pi^2 l^2 kappa^2)`` factors of eqs. 19-20 are folded into the cosines on the
panels beyond ``kappa = 1/l``. Power-law head and tail corrections close the integrals.
Achieved relative accuracy: 2e-6 against the analytic ``(8/3) r^(2/3)`` and ``2 r^(2/3)``
(no filters), 1e-5 against A_perp and A_par of Smalikho (2020), eq. 19, computed
independently by brute-force 2-D quadrature, both tested. :func:`a2` averages over 128
azimuths of the half circle (midpoint rule of a periodic function, 1e-8 relative) using
cubic log-log splines of ``A_perp`` and ``A_par`` over the lag (61 lags; relative
interpolation error 1e-7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cwproc.physics import spectra
from cwproc.physics.afunction_quadrature import (
    Panels,
    PlaneMatrix,
    cos_weights,
    integral_weights,
    panels,
    structure_integral,
)
from cwproc.physics.transfer import CWProbe, Probe, PulsedProbe

#: azimuths (on the half circle, by symmetry) of the theta-average of Smalikho (2020), eq. 15
N_THETA = 128


def longitudinal_factor(
    probe: Probe | None, p: Panels, range_m: float | None
) -> tuple[np.ndarray, float]:
    """``(factor, length)`` with ``H_par = factor * sinc^2(pi length kappa)`` at the nodes."""
    k = p.kappa
    if probe is None:
        return np.ones_like(k), 0.0
    if isinstance(probe, PulsedProbe):
        return np.exp(-2.0 * (probe.gaussian_width_m * k) ** 2), probe.delta_r_m
    if isinstance(probe, CWProbe):
        if range_m is None:
            raise ValueError("a cw probe needs range_m (the focus distance, m)")
        return probe.longitudinal(k, range_m), 0.0
    raise TypeError(f"unknown probe {probe!r}")


def _probe_scale(probe: Probe | None, range_m: float | None) -> float:
    if probe is None:
        return 0.0
    if isinstance(probe, CWProbe):
        if range_m is None:
            raise ValueError("a cw probe needs range_m (the focus distance, m)")
        return float(probe.length_scale_m(range_m))
    return float(probe.length_scale_m())


def panel_limits(
    rho_min: float,
    rho_max: float,
    *,
    probe: Probe | None,
    dy: float,
    range_m: float | None = None,
    model: spectra.Model = "inertial",
    outer_scale_m: float | None = None,
) -> tuple[float, float, bool]:
    """Wavenumber range ``(k_lo, k_hi)`` (cycles m-1) of the quadrature, and ``has_par``.

    From ``1e-5`` over the largest to ``2e3`` over the smallest length among the lags
    ``[rho_min, rho_max]`` (m), ``dy``, the probe length and the outer scale; ``2e7`` when
    one of the filters is absent (power-law tails). ``has_par`` tells whether the probe
    filters along the beam at all.
    """
    probe_len = _probe_scale(probe, range_m)
    small = [rho_min, *(s for s in (dy, probe_len) if s > 0)]
    large = [rho_max, dy, probe_len]
    if model != "inertial" and outer_scale_m is not None:
        large.append(outer_scale_m)
    has_par = probe_len > 0  # a probe of zero length filters nothing
    reach = 2e3 if (has_par and dy > 0) else 2e7
    return 1e-5 / max(large), reach / min(small), has_par


def a_curves(
    rho: ArrayLike,
    *,
    probe: Probe | None,
    dy: float,
    range_m: float | None = None,
    model: spectra.Model = "inertial",
    outer_scale_m: float | None = None,
    constant: float | None = None,
    plane: PlaneMatrix | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(A_perp(rho), A_par(rho))`` (m^(2/3)) at the lags ``rho`` (m), in one pass.

    Smalikho (2020), eqs. 16-17. Both share the inner integrals, so asking for both (and
    for many lags) costs little more than one.

    Parameters
    ----------
    rho : array_like
        Lag (m), e.g. ``l * dy``.
    probe : PulsedProbe or CWProbe or None
        Longitudinal weighting; ``None`` for a point measurement (``H_par = 1``).
    dy : float
        Transverse probe size ``dy = dtheta h / tan(phi)`` (m) in ``H_perp`` (eq. 20);
        0 for none.
    range_m : float, optional
        Focus distance (m), needed by a cw probe (``Z_R = c R^2``).
    model : {"inertial", "von_karman", "exponential"}
        Spectrum (:mod:`cwproc.physics.spectra`).
    outer_scale_m : float, optional
        ``L_V`` (m) of the finite-outer-scale models.
    constant : float, optional
        ``C`` of eq. 18 for the inertial model (default: the exact 0.065239).
    plane : PlaneMatrix, optional
        A :class:`PlaneMatrix` of the same model to take the spectrum from (used when it
        covers the wavenumbers needed; the result is identical either way).
    """
    rho_arr = np.abs(np.asarray(rho, dtype=float))
    shape = rho_arr.shape
    rho_flat = rho_arr.ravel()
    spectra._check_model(model, outer_scale_m)
    if not (math.isfinite(dy) and dy >= 0):
        raise ValueError(f"dy must be finite and >= 0, got {dy!r}")
    positive = rho_flat[rho_flat > 0]
    if positive.size == 0:
        return np.zeros(shape), np.zeros(shape)
    k_lo, k_hi, has_par = panel_limits(
        positive.min(),
        positive.max(),
        probe=probe,
        dy=dy,
        range_m=range_m,
        model=model,
        outer_scale_m=outer_scale_m,
    )
    p = panels(k_lo, k_hi)
    k = p.kappa
    fac_par, len_par = longitudinal_factor(probe, p, range_m)
    # inner integrals: G_perp(k2) = int Phi(k1, k2) H_par(k1) dk1,
    #                  G_par(k1)  = int Phi(k1, k2) H_perp(k2) dk2
    phi = None
    if plane is not None:
        same = (plane.model, plane.outer_scale_m, plane.constant) == (
            model,
            outer_scale_m,
            constant,
        )
        phi = plane.block(p) if same else None
    if phi is None:
        phi = spectra.plane_spectrum(
            k[:, None], k[None, :], model, outer_scale_m, constant=constant
        )
    u_par = integral_weights(p, len_par, fac_par)
    u_perp = integral_weights(p, dy, np.ones_like(k))
    g_perp = u_par @ phi
    g_par = phi @ u_perp
    # heads of the inner integrals: Phi is flat in the integration variable below kappa_lo
    g_perp = g_perp + phi[0, :] * fac_par[0] * p.lo
    g_par = g_par + phi[:, 0] * p.lo
    # tails of the inner integrals where no filter cuts them (Phi ~ kappa^(-8/3))
    if not has_par:
        g_perp = g_perp + phi[-1, :] * p.kappa[-1] ** (8 / 3) * p.hi ** (-5 / 3) * 0.6
    if dy == 0:
        g_par = g_par + phi[:, -1] * p.kappa[-1] ** (8 / 3) * p.hi ** (-5 / 3) * 0.6
    tail = 5.0 / 3.0 if (not has_par and dy == 0) else None
    wr = cos_weights(p, rho_flat)  # shared by both outer integrals
    a_perp_v = structure_integral(p, 2.0 * g_perp, dy, rho_flat, tail, wr)
    a_par_v = structure_integral(p, 2.0 * g_par * fac_par, len_par, rho_flat, tail, wr)
    zero = rho_flat == 0
    a_perp_v[zero] = 0.0
    a_par_v[zero] = 0.0
    return a_perp_v.reshape(shape), a_par_v.reshape(shape)


def a_plane(
    s_par: ArrayLike,
    s_perp: ArrayLike,
    *,
    probe: Probe | None,
    range_m: float | None = None,
    model: spectra.Model = "inertial",
    outer_scale_m: float | None = None,
) -> np.ndarray:
    """A-function (m^(2/3)) of a separation with components along and across the beam.

    Smalikho (2020), eqs. 16-17 generalised to a separation ``s_par`` along the beam
    and ``s_perp`` across it (m; pairs, broadcast), without transverse averaging:
    ``A = 2 int int Phi(k1, k2) H_par(k1) [1 - cos(2 pi (k1 s_par + k2 s_perp))] dk1 dk2``.
    The radial velocity averaged along the beam is axisymmetric about it, so ``s_perp``
    is the length of the whole transverse part (horizontal and vertical). Since ``Phi``
    is even in ``k2``, ``A = A_perp(s_perp) + 2 int H_par(k1) C(k1) [1 - cos(2 pi k1
    s_par)] dk1`` with ``C(k1) = int Phi(k1, k2) cos(2 pi k2 s_perp) dk2`` (the inner
    integral by the Filon-type rule of the module, the outer one as eq. 17). It equals
    ``A_perp`` at ``s_par = 0``, ``A_par`` at ``s_perp = 0`` (both tested) and, for a
    point probe, ``(8/3) s^(2/3) - (2/3) s^(2/3) (s_par / s)^2``, the inertial point pair;
    Smalikho's eq. 15 mixes ``A_perp`` and ``A_par`` of the whole length with these point
    weights instead, which misses the range weighting's dependence on the direction.
    """
    s_par, s_perp = np.broadcast_arrays(
        np.abs(np.asarray(s_par, dtype=float)), np.abs(np.asarray(s_perp, dtype=float))
    )
    shape = s_par.shape
    s1, st = s_par.ravel(), s_perp.ravel()
    spectra._check_model(model, outer_scale_m)
    out = np.zeros(s1.size)
    lengths = np.concatenate([s1[s1 > 0], st[st > 0]])
    if lengths.size == 0:
        return out.reshape(shape)
    k_lo, k_hi, _ = panel_limits(
        lengths.min(),
        lengths.max(),
        probe=probe,
        dy=0.0,
        range_m=range_m,
        model=model,
        outer_scale_m=outer_scale_m,
    )
    shared = PlaneMatrix(k_lo, k_hi, model, outer_scale_m)
    p, phi = shared.panels, shared.matrix
    fac_par, len_par = longitudinal_factor(probe, p, range_m)
    perps, which = np.unique(st, return_inverse=True)
    options = dict(probe=probe, dy=0.0, range_m=range_m, model=model, outer_scale_m=outer_scale_m)
    a_perp_v = np.concatenate(
        [a_curves(perps[i : i + 64], plane=shared, **options)[0] for i in range(0, perps.size, 64)]
    )
    # C(k1) per transverse length, in chunks (the cosine weights are (lengths, nodes))
    cross = np.concatenate(
        [phi @ cos_weights(p, perps[i : i + 64]).T for i in range(0, perps.size, 64)], axis=1
    )
    cross = cross + phi[:, [0]] * p.lo  # (n, perps)
    sel = np.flatnonzero((st == 0) & (s1 > 0))
    if sel.size:  # no transverse part: eq. 17 itself
        out[sel] = a_curves(s1[sel], plane=shared, **options)[1]
    sel = np.flatnonzero((st > 0) & (s1 > 0))
    if sel.size:  # all separations at once (plane_integral: the loop's rule in matrix form)
        from cwproc.physics import plane_integral

        smooth = 2.0 * cross[:, which[sel]] * fac_par[:, None]
        out[sel] = plane_integral.structure_integrals(p, smooth, len_par, s1[sel])
    out = out + a_perp_v[which]
    return out.reshape(shape)


def a_perp(r: ArrayLike, **options: Any) -> np.ndarray:
    """Transverse A-function ``A_perp(r)`` (m^(2/3)), Smalikho (2020), eq. 16.

    ``A_perp(r) = 2 int int Phi(k1, k2) H_par(k1) H_perp(k2) [1 - cos(2 pi r k2)] dk1 dk2``.

    Parameters
    ----------
    r : array_like
        Transverse lag (m), e.g. ``l * dy``.
    **options
        The keyword arguments of :func:`a_curves` (``probe`` and ``dy`` required).

    Returns
    -------
    numpy.ndarray
        ``A_perp`` (m^(2/3)); without filters ``(8/3) r^(2/3)`` (relative accuracy 2e-6).
    """
    return a_curves(r, **options)[0]


def a_par(r: ArrayLike, **options: Any) -> np.ndarray:
    """Longitudinal A-function ``A_par(r)`` (m^(2/3)), Smalikho (2020), eq. 17.

    ``A_par(r) = 2 int int Phi(k1, k2) H_par(k1) H_perp(k2) [1 - cos(2 pi r k1)] dk1 dk2``;
    ``options`` as :func:`a_curves`. Without filters ``2 r^(2/3)``.
    """
    return a_curves(r, **options)[1]


@dataclass(frozen=True)
class ACurves:
    """``A_perp`` and ``A_par`` of one probe/dy/model as cubic log-log splines of the lag.

    Built by :func:`a_curve_splines`; evaluates at any lag in ``[rho_min, rho_max]`` with
    relative interpolation error below 1e-6 and continues as a power law outside.
    """

    log_rho: np.ndarray
    log_perp: np.ndarray
    log_par: np.ndarray

    def _eval(self, logv: np.ndarray, rho: np.ndarray) -> np.ndarray:
        from scipy import interpolate  # here: with scipy.optimize, 0.1 s of imports

        spline = interpolate.CubicSpline(self.log_rho, logv)
        lr = np.log(np.maximum(np.asarray(rho, dtype=float), 1e-300))
        lo, hi = self.log_rho[0], self.log_rho[-1]
        inside = np.clip(lr, lo, hi)
        val = spline(inside)
        s_lo = (logv[1] - logv[0]) / (self.log_rho[1] - self.log_rho[0])
        s_hi = (logv[-1] - logv[-2]) / (self.log_rho[-1] - self.log_rho[-2])
        val = np.where(lr < lo, logv[0] + s_lo * (lr - lo), val)
        val = np.where(lr > hi, logv[-1] + s_hi * (lr - hi), val)
        return np.where(np.asarray(rho) > 0, np.exp(val), 0.0)

    def perp(self, rho: ArrayLike) -> np.ndarray:
        """``A_perp(rho)`` (m^(2/3))."""
        return self._eval(self.log_perp, np.asarray(rho, dtype=float))

    def par(self, rho: ArrayLike) -> np.ndarray:
        """``A_par(rho)`` (m^(2/3))."""
        return self._eval(self.log_par, np.asarray(rho, dtype=float))


def a_curve_splines(rho_min: float, rho_max: float, *, n: int = 61, **options: Any) -> ACurves:
    """``A_perp`` and ``A_par`` on ``n`` (at least 14 per decade) geometric lags, splined.

    The lags span ``[rho_min, rho_max]`` (m); ``options`` are the keyword arguments of
    :func:`a_curves` (``probe`` and ``dy`` required).
    """
    # at least 14 lags per decade keeps the spline error near 1e-7
    n = max(n, math.ceil(14 * math.log10(rho_max / rho_min)) + 1)
    rho = np.geomspace(rho_min, rho_max, n)
    ap, al = a_curves(rho, **options)
    return ACurves(np.log(rho), np.log(ap), np.log(al))


def _theta() -> np.ndarray:
    """Midpoint azimuths on the half circle ``(-pi/2, pi/2)``.

    The integrand of Smalikho (2020), eq. 15 depends on ``theta`` only through
    ``sin(theta)`` and ``cos^2(theta)``, so it is symmetric about ``theta = pi/2`` and the
    half circle gives the full average (Gauss-Chebyshev quadrature in ``sin(theta)``).
    """
    return -0.5 * np.pi + (np.arange(N_THETA) + 0.5) * (np.pi / N_THETA)


def transport_weights(mu: ArrayLike, phi_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth-dependent factors of Smalikho (2020), eq. 15.

    Returns ``(sqrt_g, w_perp, w_par)`` of shape ``mu.shape + (N_THETA,)``:
    ``g = (1 - mu sin th)^2 + (mu cos th)^2``, ``w_perp = sin^2 phi + cos^2 phi
    (1 - mu sin th)^2 / g``, ``w_par = cos^2 phi (mu cos th)^2 / g``.
    """
    mu = np.asarray(mu, dtype=float)[..., None]
    th = _theta()
    a = 1.0 - mu * np.sin(th)
    b = mu * np.cos(th)
    g = a**2 + b**2
    s2 = math.sin(math.radians(phi_deg)) ** 2
    c2 = math.cos(math.radians(phi_deg)) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        wp = np.where(g > 0, s2 + c2 * a**2 / g, 1.0)
        wl = np.where(g > 0, c2 * b**2 / g, 0.0)
    return np.sqrt(g), wp, wl


def a2_from_curves(curves: ACurves, lag_m: ArrayLike, mu: ArrayLike, phi_deg: float) -> np.ndarray:
    """``A_2`` (m^(2/3)) of Smalikho (2020), eq. 15 from splined ``A_perp``, ``A_par``.

    ``lag_m`` (``l dy``, m) and ``mu`` broadcast; the theta-average is the trapezoid rule
    over :data:`N_THETA` azimuths.
    """
    lag_m = np.asarray(lag_m, float)
    sg, wp, wl = transport_weights(mu, phi_deg)  # weights depend on mu only
    rho = lag_m[..., None] * sg
    return np.mean(wp * curves.perp(rho) + wl * curves.par(rho), axis=-1)


def a2(
    lag_number: ArrayLike,
    dy: float,
    mu: ArrayLike,
    phi_deg: float,
    *,
    probe: Probe | None,
    range_m: float | None = None,
    model: spectra.Model = "inertial",
    outer_scale_m: float | None = None,
    constant: float | None = None,
) -> np.ndarray:
    """Method-2 A-function ``A_2(l dy)`` (m^(2/3)), Smalikho (2020), eq. 15.

    ``A_2 = (1/2pi) int dth {[sin^2 phi + cos^2 phi (1 - mu sin th)^2/g] A_perp(l dy sqrt g)
    + cos^2 phi (mu cos th)^2/g A_par(l dy sqrt g)}``, ``g = (1 - mu sin th)^2 +
    (mu cos th)^2``; ``H_perp`` of ``A_perp``/``A_par`` keeps the fixed ``dy``. At
    ``mu = 0`` it equals ``A_perp(l dy)`` (method 1).

    Parameters
    ----------
    lag_number : array_like
        Lag number(s) ``l`` (1); broadcast with ``mu``.
    dy : float
        Transverse sampling ``dy = dtheta h / tan(phi)`` (m), > 0.
    mu : array_like
        ``mu = U / V_s``, mean wind over linear scan speed (1).
    phi_deg : float
        Elevation angle of the cone (degrees).
    probe, range_m, model, outer_scale_m, constant
        As :func:`a_curves`.
    """
    lag_number, mu = np.broadcast_arrays(
        np.asarray(lag_number, dtype=float), np.asarray(mu, dtype=float)
    )
    if not dy > 0:
        raise ValueError("dy must be > 0")
    lmax = float(np.max(lag_number))
    mmax = float(np.max(mu))
    curves = a_curve_splines(
        0.02 * dy,
        lmax * dy * (1.0 + mmax) * 1.01,
        probe=probe,
        dy=dy,
        range_m=range_m,
        model=model,
        outer_scale_m=outer_scale_m,
        constant=constant,
    )
    return a2_from_curves(curves, lag_number * dy, mu, phi_deg)
