"""Exact two-beam statistics of probe-averaged radial velocities (any azimuth step).

The radial velocity of one ray is the wind projected on the beam and averaged over the
probe volume (Banakh et al. (1999), eqs. 12, 15):

.. math::

    V_D(a) = \\sum_j w_j\\, \\mathbf S_{aj}\\cdot\\mathbf V(\\mathbf x_{aj}, t_a),

with nodes ``x_aj = z_j S_aj`` along the beam (range weighting ``Q``, e.g. the pulsed
gate of Smalikho (2020), eq. 19 or the cw Lorentzian ``Q_s``) and, for a ray accumulated
while the beam sweeps, several sub-beams ``S_aj`` across the azimuth interval (the
transverse averaging of Smalikho (2020), eq. 20). With frozen turbulence transported by
the mean wind ``U`` (Taylor), ``V(x, t) = V'(x - U t)``, so two rays see the separations
``r = x_aj - x_bk - U (t_a - t_b)`` (Banakh et al. (1999), eq. 15; the printed '+' is the
opposite sign convention for ``U``).

Isotropic turbulence: the correlation tensor (Banakh et al. (1999), eq. 16)
``B_ik = sigma^2 [g delta_ik + (f - g) r_i r_k / r^2]`` and the structure tensor
``D_ik = 2 sigma^2 delta_ik - 2 B_ik = D_tt delta_ik + (D_ll - D_tt) r_i r_k / r^2``,
with ``D_ll``, ``D_tt`` of :mod:`cwproc.physics.spectra` (inertial:
``2 eps^(2/3) r^(2/3)`` and ``(8/3) eps^(2/3) r^(2/3)``, Smalikho (2020), eqs. 12-13).

Structure function of two rays ``a``, ``b`` (``S_a = sum_j w_j S_aj``):

.. math::

    D(a, b) = \\langle [V_D(a) - V_D(b)]^2\\rangle
            = \\sigma^2 |\\bar{\\mathbf S}_a - \\bar{\\mathbf S}_b|^2
              + \\sum_{jk} w_j w_k\\, S_{aj}^T D(r_{aj,bk}) S_{bk}
              - \\tfrac12 \\sum_{jk} w_j w_k\\, S_{aj}^T D(r_{aj,ak}) S_{ak}
              - \\tfrac12 \\sum_{jk} w_j w_k\\, S_{bj}^T D(r_{bj,bk}) S_{bk},

the identity ``B = sigma^2 I - D/2`` applied to ``B_aa + B_bb - 2 B_ab``. The first term is
the large-scale (uniform) wind seen along two different directions; it is finite only
with an outer scale (von Karman, exponential). The inertial (Kolmogorov) model has no
finite ``sigma^2``; its two-beam structure function is defined without that term, which
is the small-angle model of Smalikho (2020), eqs. 15-17 (two parallel beams): for
``dtheta -> 0`` and no wind :func:`two_beam_structure_function` tends to
``A_perp(l dy)`` (eq. 16; ``(8/3) r^(2/3)`` for a point probe), tested.

The same-beam terms hold the ``r^(2/3)`` cusp at ``r = 0``; they use the same pair rule
as the cross terms (:func:`beam_quadrature`), so that the cusps of nearly parallel beams
cancel consistently.

Everything is returned per ``eps^(2/3)`` times ``epsilon^(2/3)`` (``epsilon = 1`` gives the
exact "A-function" of the pair, m^(2/3)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.polynomial import legendre
from numpy.typing import ArrayLike
from scipy import special

from cwproc.physics import spectra
from cwproc.physics.cw_probe import lorentzian_quadrature
from cwproc.physics.geometry import beam_unit_vector_une

#: nodes of the pulsed pair rule: per half of the range difference u, and along v
N_U = 40
N_V = 24
#: nodes of the cw Lorentzian rule
CW_NODES = 120
#: half width of the pulsed quadrature interval beyond the gate, in Gaussian 1/e widths
_PULSE_REACH = 4.0


@dataclass(frozen=True)
class BeamQuadrature:
    """Node pairs of the double range integral ``int int Q(z_a) Q(z_b) F dz_a dz_b``.

    ``z_a``, ``z_b`` (m from the lidar) and ``weights`` (sum 1) of the pairs. Pulsed
    probes use difference/mean coordinates ``u = z_a - z_b``, ``v = (z_a + z_b)/2``,
    nodes graded towards ``u = 0`` where the ``r^(2/3)`` cusp of nearly parallel beams
    lies (:func:`pulsed_pairs`); cw probes the product of the Lorentzian rule.
    """

    z_a: np.ndarray
    z_b: np.ndarray
    weights: np.ndarray


def _gauss(lo: float, hi: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = legendre.leggauss(n)
    return 0.5 * (hi - lo) * x + 0.5 * (hi + lo), 0.5 * (hi - lo) * w


def pulsed_weighting(s: ArrayLike, pulse_width_m: float, gate_m: float) -> np.ndarray:
    """Range weighting ``Q(s)`` (m-1) of a pulsed lidar, ``s`` from the gate centre (m).

    The Gaussian pulse ``exp(-s^2/a^2)/(sqrt(pi) a)`` convolved with the gate of length
    ``dR`` (Smalikho (2020), eq. 19: its Fourier transform is ``exp(-(pi a kappa)^2)
    sinc(pi dR kappa)``): ``[erf((s + dR/2)/a) - erf((s - dR/2)/a)] / (2 dR)``.

    Parameters
    ----------
    s : array_like
        Distance from the gate centre along the beam (m).
    pulse_width_m : float
        ``a`` (m), the 1/e half width of the pulse (Stream Line ``dp = 15.3 m``).
    gate_m : float
        ``dR`` (m), the gate length; 0 gives the Gaussian alone.
    """
    s = np.asarray(s, dtype=float)
    a = float(pulse_width_m)
    if gate_m <= 0:
        return np.exp(-((s / a) ** 2)) / (math.sqrt(math.pi) * a)
    half = 0.5 * gate_m
    return (special.erf((s + half) / a) - special.erf((s - half) / a)) / (2.0 * gate_m)


def pulsed_pairs(
    range_m: float, pulse_width_m: float, gate_m: float, n_u: int = N_U, n_v: int = N_V
) -> BeamQuadrature:
    """Pair rule of the pulsed weighting (:func:`pulsed_weighting`) of both beams.

    ``u = z_a - z_b`` on ``[-2 s_max, 2 s_max]`` (``s_max = dR/2 + 4 a``), each half by
    Gauss-Legendre in ``t`` with ``u = +-2 s_max t^2`` (nodes dense near the cusp at 0);
    ``v`` by Gauss-Legendre on ``[-(s_max - |u|/2), s_max - |u|/2]``; weights
    ``Q(v + u/2) Q(v - u/2)`` times the Jacobian, renormalised to 1.
    """
    s_max = 0.5 * gate_m + _PULSE_REACH * pulse_width_m
    t, wt = _gauss(0.0, 1.0, n_u)
    u_half = 2.0 * s_max * t**2
    wu_half = 2.0 * s_max * 2.0 * t * wt
    u = np.concatenate([-u_half[::-1], u_half])
    wu = np.concatenate([wu_half[::-1], wu_half])
    x, wx = legendre.leggauss(n_v)
    half = s_max - 0.5 * np.abs(u)  # (nu,)
    v = half[:, None] * x[None, :]
    wv = half[:, None] * wx[None, :]
    sa = v + 0.5 * u[:, None]
    sb = v - 0.5 * u[:, None]
    w = wu[:, None] * wv * pulsed_weighting(sa, pulse_width_m, gate_m)
    w = w * pulsed_weighting(sb, pulse_width_m, gate_m)
    w = w / w.sum()
    return BeamQuadrature(range_m + sa.ravel(), range_m + sb.ravel(), w.ravel())


def beam_quadrature(probe: Any, range_m: float) -> BeamQuadrature:
    """:class:`BeamQuadrature` of a probe (PulsedProbe, CWProbe or None) at ``range_m`` (m).

    Pulsed: :func:`pulsed_pairs` with ``a = gaussian_width_m / pi`` (so ``"printed"``
    probes keep their transfer function). cw: the product of the cut Lorentzian ``Q_s``
    rule of Banakh et al. (1999) (:func:`cwproc.physics.cw_probe.lorentzian_quadrature`,
    :data:`CW_NODES` nodes; one rule for the cross and the same-beam terms, so that their
    cusps cancel at small separations: 0.3 % from the 300-node limit at 8 m separation of
    a 65 m probe). ``None``: a point.
    """
    r = float(range_m)
    if probe is None:
        one = np.array([r])
        return BeamQuadrature(one, one, np.ones(1))
    if hasattr(probe, "rayleigh_half_width"):
        q = lorentzian_quadrature(
            float(probe.centre_range(r)), float(probe.rayleigh_half_width(r)), CW_NODES, 1
        )
        za, zb = np.meshgrid(q.z, q.z, indexing="ij")
        return BeamQuadrature(za.ravel(), zb.ravel(), np.outer(q.w, q.w).ravel())
    a = float(probe.gaussian_width_m) / math.pi
    if a <= 0:
        raise ValueError("a pulsed probe needs a pulse width > 0")
    return pulsed_pairs(r, a, float(probe.delta_r_m))


def _sweep_offsets(sweep_deg: float, n_sweep: int) -> np.ndarray:
    """Midpoint sub-beam azimuth offsets (deg) across a swept ray."""
    if n_sweep < 1:
        raise ValueError("n_sweep must be >= 1")
    if sweep_deg == 0 or n_sweep == 1:
        return np.zeros(1)
    return ((np.arange(n_sweep) + 0.5) / n_sweep - 0.5) * sweep_deg


def _structure_parts(
    r: np.ndarray, model: str, outer_scale_m: float | None
) -> tuple[np.ndarray, np.ndarray]:
    """``D_ll(r)``, ``D_tt(r)`` per eps^(2/3) (m^(2/3)), :mod:`cwproc.physics.spectra`."""
    d_ll = spectra.longitudinal_structure_function(r, model, outer_scale_m)
    d_tt = spectra.transverse_structure_function(r, model, outer_scale_m)
    return d_ll, d_tt


def _contract(
    r_vec: np.ndarray, sa: np.ndarray, sb: np.ndarray, model: str, outer: float | None
) -> np.ndarray:
    """``S_a^T D(r) S_b`` per eps^(2/3), broadcast over leading axes."""
    r = np.sqrt(np.sum(r_vec * r_vec, axis=-1))
    d_ll, d_tt = _structure_parts(r, model, outer)
    safe = np.where(r > 0, r, 1.0)
    pa = np.sum(sa * r_vec, axis=-1) / safe
    pb = np.sum(sb * r_vec, axis=-1) / safe
    dot = np.sum(sa * sb, axis=-1)
    return d_tt * dot + (d_ll - d_tt) * pa * pb


def same_beam_term(
    quadrature: BeamQuadrature,
    elevation_deg: float,
    *,
    model: str = "inertial",
    outer_scale_m: float | None = None,
    sweep_deg: float = 0.0,
    n_sweep: int = 1,
    sweep_shift_m: ArrayLike | None = None,
) -> float:
    """``(1/2) sum_jk w_j w_k S_j^T D(x_j - x_k) S_k`` of one ray, per eps^(2/3) (m^(2/3)).

    The same-beam part of :func:`two_beam_structure_function`: the mean square deviation
    of the probe-averaged from the point velocities, i.e. half the structure function the
    probe averaging removes. Independent of the azimuth.
    """
    return 0.5 * float(
        cross_term(
            0.0,
            0.0,
            elevation_deg,
            quadrature,
            model=model,
            outer_scale_m=outer_scale_m,
            sweep_deg=sweep_deg,
            n_sweep=n_sweep,
            sweep_shift_m=sweep_shift_m,
        )
    )


def cross_term(
    azimuth_a_deg: ArrayLike,
    azimuth_b_deg: ArrayLike,
    elevation_deg: ArrayLike,
    quadrature: BeamQuadrature,
    *,
    separation_m: ArrayLike | None = None,
    model: str = "inertial",
    outer_scale_m: float | None = None,
    sweep_deg: float = 0.0,
    n_sweep: int = 1,
    sweep_shift_m: ArrayLike | None = None,
) -> np.ndarray:
    """``sum_jk w_j w_k S_aj^T D(x_aj - x_bk - d) S_bk`` per eps^(2/3) (m^(2/3)).

    ``d`` (``separation_m``, ``(..., 3)`` up/north/east, m) is the transport ``U (t_a -
    t_b)`` between the ray centres; ``sweep_shift_m`` (``(..., 3)``) the transport ``U tau`` during
    one swept ray of duration ``tau`` (sub-beam ``i`` is seen at ``tau offset_i /
    sweep``). Inputs broadcast; shape of the broadcast azimuths.
    """
    az_a, az_b, el = np.broadcast_arrays(
        np.asarray(azimuth_a_deg, float),
        np.asarray(azimuth_b_deg, float),
        np.asarray(elevation_deg, float),
    )
    shape = az_a.shape
    d = np.zeros(3) if separation_m is None else np.asarray(separation_m, dtype=float)
    d = np.broadcast_to(d, (*shape, 3)).reshape(-1, 3)
    offsets = _sweep_offsets(sweep_deg, n_sweep)
    oa, ob = (o.ravel() for o in np.meshgrid(offsets, offsets, indexing="ij"))
    ws = 1.0 / offsets.size**2
    frac = offsets / sweep_deg if sweep_deg else np.zeros_like(offsets)
    fa, fb = (f.ravel() for f in np.meshgrid(frac, frac, indexing="ij"))
    shift = np.zeros(3) if sweep_shift_m is None else np.asarray(sweep_shift_m, float)
    shift = np.broadcast_to(shift, (*shape, 3)).reshape(-1, 3)
    za, zb, wq = quadrature.z_a, quadrature.z_b, quadrature.weights
    az_a, az_b, el = az_a.ravel(), az_b.ravel(), el.ravel()
    out = np.zeros(az_a.size)
    chunk = max(1, 200_000 // za.size)
    for i in range(0, az_a.size, chunk):
        sl = slice(i, i + chunk)
        for o_a, o_b, f_a, f_b in zip(oa, ob, fa, fb, strict=True):  # sub-beam pairs
            sa = beam_unit_vector_une(az_a[sl] + o_a, el[sl])[:, None, :]  # (P, 1, 3)
            sb = beam_unit_vector_une(az_b[sl] + o_b, el[sl])[:, None, :]
            dd = d[sl] + (f_a - f_b) * shift[sl]
            r_vec = za[None, :, None] * sa - zb[None, :, None] * sb - dd[:, None, :]
            out[sl] += ws * (_contract(r_vec, sa, sb, model, outer_scale_m) @ wq)
    return out.reshape(shape)


def mean_direction(
    azimuth_deg: ArrayLike, elevation_deg: ArrayLike, sweep_deg: float = 0.0, n_sweep: int = 1
) -> np.ndarray:
    """``S_bar = sum_j w_j S_j`` of a (possibly swept) ray, ``(..., 3)``."""
    offsets = _sweep_offsets(sweep_deg, n_sweep)
    az = np.asarray(azimuth_deg, float)[..., None] + offsets
    return beam_unit_vector_une(az, np.asarray(elevation_deg, float)[..., None]).mean(axis=-2)


@dataclass(frozen=True)
class PairGeometry:
    """Two rays of a scan as :func:`two_beam_structure_function` sees them.

    Attributes
    ----------
    quadrature : BeamQuadrature
        Range weighting along each beam.
    azimuth_a_deg, azimuth_b_deg, elevation_deg : numpy.ndarray
        Azimuths and elevation of the rays (deg), broadcast with the time separation.
    shift_m : numpy.ndarray
        ``U (t_a - t_b)`` (m), ``(..., 3)``: the transport between the rays.
    sweep_deg, n_sweep : float, int
        Azimuth swept during one ray (deg) and its sub-beams.
    sweep_shift_m : numpy.ndarray
        ``U tau`` (m), ``(3,)``: the transport while one ray is accumulated.
    """

    quadrature: BeamQuadrature
    azimuth_a_deg: np.ndarray
    azimuth_b_deg: np.ndarray
    elevation_deg: np.ndarray
    shift_m: np.ndarray
    sweep_deg: float
    n_sweep: int
    sweep_shift_m: np.ndarray

    def cross(self, a: np.ndarray, b: np.ndarray, shift: bool, **model: Any) -> np.ndarray:
        """:func:`cross_term` of azimuths ``a`` and ``b`` with this pair's sweep.

        ``shift``: with the transport ``shift_m`` between the rays (else none);
        ``model``: ``model`` and ``outer_scale_m``.
        """
        separation = {"separation_m": self.shift_m} if shift else {}
        return cross_term(
            a,
            b,
            self.elevation_deg,
            self.quadrature,
            sweep_deg=self.sweep_deg,
            n_sweep=self.n_sweep,
            sweep_shift_m=self.sweep_shift_m,
            **separation,
            **model,
        )


def pair_geometry(
    azimuth_a_deg: ArrayLike,
    azimuth_b_deg: ArrayLike,
    elevation_deg: ArrayLike,
    range_m: float,
    *,
    probe: Any = None,
    quadrature: BeamQuadrature | None = None,
    time_separation_s: ArrayLike = 0.0,
    mean_wind: ArrayLike | None = None,
    sweep_deg: float = 0.0,
    n_sweep: int = 1,
    ray_duration_s: float = 0.0,
) -> PairGeometry:
    """The :class:`PairGeometry` of two rays.

    Parameters
    ----------
    azimuth_a_deg, azimuth_b_deg : array_like
        Azimuths of the two rays (deg, clockwise from north); broadcast with
        ``elevation_deg`` and ``time_separation_s``.
    elevation_deg : array_like
        Elevation of the rays (deg).
    range_m : float
        Distance of the gate (pulsed) or focus (cw) from the lidar (m).
    probe : PulsedProbe or CWProbe or None
        Range weighting (:func:`beam_quadrature`); ``None`` and no ``quadrature``: a point.
    quadrature : BeamQuadrature, optional
        Overrides ``probe``.
    time_separation_s : array_like
        ``t_a - t_b`` (s).
    mean_wind : array_like, optional
        ``U`` (up, north, east) (m s-1), frozen-turbulence transport; ``None``: none.
    sweep_deg, n_sweep : float, int
        Azimuth swept during one ray (deg; 0 for step-stare) and its sub-beams.
    ray_duration_s : float
        Accumulation time of one swept ray (s): the wind moves the field by ``U tau``
        while the beam sweeps (continuous scans: ``tau = T_scan / M``).
    """
    q = quadrature if quadrature is not None else beam_quadrature(probe, range_m)
    az_a, az_b, el, t = np.broadcast_arrays(
        np.asarray(azimuth_a_deg, float),
        np.asarray(azimuth_b_deg, float),
        np.asarray(elevation_deg, float),
        np.asarray(time_separation_s, dtype=float),
    )
    wind = np.zeros(3) if mean_wind is None else np.asarray(mean_wind, dtype=float)
    return PairGeometry(
        q, az_a, az_b, el, wind * t[..., None], sweep_deg, n_sweep, wind * ray_duration_s
    )


def two_beam_structure_function(
    azimuth_a_deg: ArrayLike,
    azimuth_b_deg: ArrayLike,
    elevation_deg: ArrayLike,
    range_m: float,
    *,
    model: str = "inertial",
    epsilon: float = 1.0,
    outer_scale_m: float | None = None,
    **pair: Any,
) -> np.ndarray:
    """``<[V_D(a) - V_D(b)]^2>`` of two probe-averaged radial velocities (m2 s-2).

    The exact two-beam model of the module docstring (Banakh et al. (1999), eqs. 15-16 in
    structure-tensor form): chord separation of the probe volumes, the angle between the
    beams, range weighting along both beams, sweep averaging across each ray and the
    transport ``U (t_a - t_b)``.

    Parameters
    ----------
    azimuth_a_deg, azimuth_b_deg, elevation_deg, range_m
        The rays, as :func:`pair_geometry`.
    model : {"inertial", "von_karman", "exponential"}
        Turbulence model (:mod:`cwproc.physics.spectra`).
    epsilon : float
        Dissipation rate (m2 s-3); 1 returns the pair's exact A-function (m^(2/3)).
    outer_scale_m : float, optional
        ``L_V`` (m) of the finite-outer-scale models.
    **pair
        ``probe``, ``quadrature``, ``time_separation_s``, ``mean_wind``, ``sweep_deg``,
        ``n_sweep``, ``ray_duration_s`` of :func:`pair_geometry`.

    Returns
    -------
    numpy.ndarray
        ``D`` (m2 s-2), broadcast shape of the inputs.
    """
    spectra._check_model(model, outer_scale_m)
    g = pair_geometry(azimuth_a_deg, azimuth_b_deg, elevation_deg, range_m, **pair)
    az_a, az_b, el = g.azimuth_a_deg, g.azimuth_b_deg, g.elevation_deg
    turbulence = dict(model=model, outer_scale_m=outer_scale_m)
    out = np.asarray(g.cross(az_a, az_b, True, **turbulence), dtype=float)
    moving = bool(np.any(g.sweep_shift_m != 0)) and g.sweep_deg != 0 and g.n_sweep > 1
    if moving:  # a ray seen at its own times: its same-beam term depends on the azimuth
        out = out - 0.5 * (
            g.cross(az_a, az_a, False, **turbulence) + g.cross(az_b, az_b, False, **turbulence)
        )
    else:
        for e in np.unique(el):
            self_term = same_beam_term(
                g.quadrature,
                float(e),
                model=model,
                outer_scale_m=outer_scale_m,
                sweep_deg=g.sweep_deg,
                n_sweep=g.n_sweep,
            )
            out = np.where(el == e, out - 2.0 * self_term, out)
    if model != "inertial":
        sigma2 = spectra.variance_per_eps23(model, float(outer_scale_m))
        diff = mean_direction(az_a, el, g.sweep_deg, g.n_sweep) - mean_direction(
            az_b, el, g.sweep_deg, g.n_sweep
        )
        out = out + sigma2 * np.sum(diff * diff, axis=-1)
    return float(epsilon) ** (2.0 / 3.0) * out


def dwell_structure_function(
    azimuth_a_deg: ArrayLike,
    azimuth_b_deg: ArrayLike,
    elevation_deg: float,
    range_m: float,
    *,
    dwell_s: float,
    n_dwell: int = 16,
    time_separation_s: ArrayLike = 0.0,
    mean_wind: ArrayLike | None = None,
    probe: Any = None,
    quadrature: BeamQuadrature | None = None,
    model: str = "inertial",
    epsilon: float = 1.0,
    outer_scale_m: float | None = None,
) -> np.ndarray:
    """``<[V_a - V_b]^2>`` (m2 s-2) of two step-stare rays that each dwell ``dwell_s``.

    A step-stare ray holds its azimuth while it accumulates pulses (``T_d`` = pulses per
    ray / pulse repetition rate) and the mean wind carries the frozen field past: the ray
    is the mean of ``n_dwell`` point-in-time rays at offsets ``o_j`` (midpoints of
    ``[0, T_d)``). Directly, by :func:`cross_term` over all sub-ray pairs,

    ``D = mean_jk C(a, b; U (t_a - t_b + o_j - o_k)) - (1/2) mean_jk [C(a, a; U (o_j -
    o_k)) + C(b, b; U (o_j - o_k))]``

    (``C`` the cross term; plus ``sigma_V^2 |S_a - S_b|^2`` for finite outer scales), the
    reference of :func:`cwproc.physics.atable_swept.dwell_kernel`. ``time_separation_s``
    is ``t_a - t_b`` of the rays' starts; other parameters as
    :func:`two_beam_structure_function` (``elevation_deg`` a scalar).
    """
    spectra._check_model(model, outer_scale_m)
    q = quadrature if quadrature is not None else beam_quadrature(probe, range_m)
    az_a, az_b, t = np.broadcast_arrays(
        np.asarray(azimuth_a_deg, float),
        np.asarray(azimuth_b_deg, float),
        np.asarray(time_separation_s, float),
    )
    wind = np.zeros(3) if mean_wind is None else np.asarray(mean_wind, dtype=float)
    offsets = (np.arange(n_dwell) + 0.5) / n_dwell * float(dwell_s)
    lag = (offsets[:, None] - offsets[None, :]).ravel()  # o_j - o_k
    turbulence = dict(model=model, outer_scale_m=outer_scale_m)

    def averaged(first: np.ndarray, second: np.ndarray, dt: np.ndarray) -> np.ndarray:
        shift = wind * (dt[..., None] + lag)[..., None]  # (..., n_dwell^2, 3)
        shape = (*first.shape, lag.size)
        c = cross_term(
            np.broadcast_to(first[..., None], shape),
            np.broadcast_to(second[..., None], shape),
            elevation_deg,
            q,
            separation_m=shift,
            **turbulence,
        )
        return c.mean(axis=-1)

    zero = np.zeros_like(t)
    out = averaged(az_a, az_b, t) - 0.5 * (averaged(az_a, az_a, zero) + averaged(az_b, az_b, zero))
    if model != "inertial":
        sigma2 = spectra.variance_per_eps23(model, float(outer_scale_m))
        diff = beam_unit_vector_une(az_a, elevation_deg) - beam_unit_vector_une(az_b, elevation_deg)
        out = out + sigma2 * np.sum(diff * diff, axis=-1)
    return float(epsilon) ** (2.0 / 3.0) * out


def two_beam_covariance(
    azimuth_a_deg: ArrayLike,
    azimuth_b_deg: ArrayLike,
    elevation_deg: ArrayLike,
    range_m: float,
    *,
    outer_scale_m: float,
    model: str = "von_karman",
    epsilon: float = 1.0,
    **pair: Any,
) -> np.ndarray:
    """Covariance ``<V_D(a) V_D(b)>`` (m2 s-2) of two probe-averaged radial velocities.

    Finite-outer-scale models only (``sigma^2 = (eps L_V / c)^(2/3)``, Banakh et al.
    (1999), eq. 19): ``B_ab = sigma^2 S_a . S_b - (1/2) sum_jk w_j w_k S_aj^T D(r) S_bk``
    (``B = sigma^2 I - D/2``); the same ray (``a = b``, ``t = 0``) uses the same pair rule.
    Parameters as :func:`two_beam_structure_function`. ``D(a, b) = B_aa + B_bb - 2 B_ab``
    holds exactly.
    """
    if model == "inertial":
        raise ValueError("the inertial model has no finite covariance; use von_karman")
    spectra._check_model(model, outer_scale_m)
    g = pair_geometry(azimuth_a_deg, azimuth_b_deg, elevation_deg, range_m, **pair)
    sigma2 = spectra.variance_per_eps23(model, float(outer_scale_m))
    sa = mean_direction(g.azimuth_a_deg, g.elevation_deg, g.sweep_deg, g.n_sweep)
    sb = mean_direction(g.azimuth_b_deg, g.elevation_deg, g.sweep_deg, g.n_sweep)
    out = sigma2 * np.sum(sa * sb, axis=-1)
    # one pair rule for all pairs, the same ray included (consistent cusps)
    cross = g.cross(
        g.azimuth_a_deg, g.azimuth_b_deg, True, model=model, outer_scale_m=outer_scale_m
    )
    return float(epsilon) ** (2.0 / 3.0) * (out - 0.5 * cross)
