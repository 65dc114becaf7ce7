"""Doppler beam swinging (DBS): wind and velocity variances from four inclined beams.

A WindCube points its beam at the azimuths 0, 90, 180, 270 deg on a cone of half-angle
``theta`` from the zenith, and (v2, v2.1) straight up. With the beam unit vector
``s = (sin theta sin phi, sin theta cos phi, cos theta)`` (east, north, up) the radial
velocity is ``V_r = s . V``, and one cycle of beams gives

.. math::

    u = \\frac{V_{90} - V_{270}}{2\\sin\\theta},\\quad
    v = \\frac{V_{0} - V_{180}}{2\\sin\\theta},\\quad w = V_V
    \\;(\\text{or } \\textstyle\\sum_k V_k / (4\\cos\\theta) \\text{ without a vertical beam}).

Every estimate is a linear combination ``sum_k a_k V_k`` of radial velocities measured
at different places (the beams are ``2 h tan theta`` apart at height ``h``) and times
(one line of sight after another), each averaged along its beam by the pulsed range
weighting. Its variance is therefore not the variance of the wind component: Sathe et
al. (2011) show that the DBS variances mix in the variances and covariances of the
other components ("cross-contamination") and lose the small scales averaged over the
probe volume. Under the assumptions below the ratio

.. math::

    \\rho = \\frac{\\operatorname{var}(\\sum_k a_k \\bar V_k)}{\\sigma^2}
          = \\frac{1}{\\sigma^2}\\sum_{k,l} a_k a_l \\iint Q(s)Q(s')\\,
            \\mathbf s_k\\cdot B(\\mathbf r_{kl} + s'\\mathbf s_l - s\\mathbf s_k)\\cdot
            \\mathbf s_l\\, ds\\, ds'

is computed exactly (quadrature) with the isotropic correlation tensor ``B`` of
von Karman turbulence (Banakh et al. (1999), eq. 16; :mod:`cwproc.physics.correlation`),
``r_kl`` the separation of the two gates in the frozen field carried by the mean wind
(``p_l - p_k - U (t_l - t_k)``, Taylor's hypothesis) and ``Q`` the pulsed range
weighting (:func:`range_nodes`). ``rho`` with point probes is
the cross-contamination alone; ``rho`` of one beam with itself is the volume averaging
alone (the pulsed analogue of the cw correction of :mod:`cwproc.physics.volume_averaging`).

Assumptions (flagged where they fail, see :mod:`cwproc.stages.dbs`): horizontally
homogeneous flow across the cone (fails in complex terrain: the four beams see
different mean winds), isotropic von Karman turbulence with a known integral scale,
frozen turbulence over one beam cycle, the noise white and independent between lines of
sight. The noise variance of each radial velocity follows from its CNR
(:func:`cwproc.physics.noise.velocity_noise_std`, Pearson et al. (2009), eq. 3), which
holds only above the lidar's detection threshold (low CNR: outliers, not white noise).

References: Sathe A., Mann J., Gottschall J., Courtney M.S. (2011), Can wind lidars
measure turbulence?, J. Atmos. Oceanic Technol. 28, 853-868; Sathe A., Mann J. (2013),
A review of turbulence measurements using ground-based wind lidars, Atmos. Meas. Tech.
6, 3147-3167; Banakh et al. (1999), eq. 16; Pearson et al. (2009), eq. 3.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from cwproc.physics.correlation import correlation_tensor
from cwproc.physics.geometry import beam_unit_vector
from cwproc.physics.two_beam import pulsed_weighting
from cwproc.references import SATHE_2011, SATHE_MANN_2013

__all__ = [
    "SATHE_2011",
    "SATHE_MANN_2013",
    "along_wind_coefficients",
    "dbs_beam_unit_vector",
    "estimator_coefficients",
    "estimator_variance_ratio",
    "noise_variance",
    "range_nodes",
]


#: the inclined beams' azimuths (deg) of a WindCube DBS cycle
INCLINED = ("0", "90", "180", "270")


def dbs_beam_unit_vector(beam: str, scan_angle_deg: float) -> np.ndarray:
    """Unit vector (east, north, up) of beam ``"0"``...``"270"`` or ``"V"``."""
    if beam == "V":
        return np.array([0.0, 0.0, 1.0])
    return beam_unit_vector(float(beam), 90.0 - scan_angle_deg)


def estimator_coefficients(
    component: str, scan_angle_deg: float, vertical_beam: bool = True
) -> dict[str, float]:
    """The coefficients ``a_k`` of the DBS estimate of ``"u"``, ``"v"`` or ``"w"``."""
    s = np.sin(np.deg2rad(scan_angle_deg))
    if component == "u":
        return {"90": 0.5 / s, "270": -0.5 / s}
    if component == "v":
        return {"0": 0.5 / s, "180": -0.5 / s}
    if component == "w":
        if vertical_beam:
            return {"V": 1.0}
        c = np.cos(np.deg2rad(scan_angle_deg))
        return {b: 0.25 / c for b in INCLINED}
    raise ValueError(f"component must be u, v or w, got {component!r}")


def along_wind_coefficients(
    u_mean: float, v_mean: float, scan_angle_deg: float
) -> dict[str, float]:
    """Coefficients of the along-wind component ``(u U_x + v U_y) / |U|`` (its TI)."""
    speed = float(np.hypot(u_mean, v_mean))
    cu, cv = (
        estimator_coefficients("u", scan_angle_deg),
        estimator_coefficients("v", scan_angle_deg),
    )
    out = {k: a * u_mean / speed for k, a in cu.items()}
    out.update({k: a * v_mean / speed for k, a in cv.items()})
    return out


def estimator_variance_ratio(
    coefficients: Mapping[str, float],
    *,
    height_m: float,
    scan_angle_deg: float,
    beam_time_s: Mapping[str, float],
    mean_wind: np.ndarray,
    integral_scale_m: float,
    range_nodes: tuple[np.ndarray, np.ndarray] | None = None,
    component: np.ndarray | None = None,
) -> float:
    """``rho`` = var(DBS estimate) / sigma^2 of isotropic von Karman turbulence.

    Parameters
    ----------
    coefficients : mapping
        ``a_k`` per beam label (:func:`estimator_coefficients`).
    height_m : float
        Altitude of the gates (m); inclined gates at range ``h / cos theta``.
    scan_angle_deg : float
        Cone half-angle from the zenith (deg).
    beam_time_s : mapping
        Time of each beam within its cycle (s).
    mean_wind : ndarray
        Mean wind (east, north, up) (m s-1) carrying the frozen field.
    integral_scale_m : float
        Longitudinal integral scale L_V of the von Karman model (m).
    range_nodes : (nodes, weights), optional
        Quadrature of the range weighting along the beam (m, weights summing to 1),
        :func:`range_nodes`; None: point probes.
    component : ndarray, optional
        Unit vector of the wind component the estimate stands for (its variance is the
        denominator); by isotropy every component has the variance ``sigma^2``, so it
        only documents the intent.

    Returns
    -------
    float
        ``rho`` (1): 1 for a perfect estimate; > 1 cross-contamination dominates, < 1
        the probe's averaging does.
    """
    del component  # isotropy: sigma^2 of every component
    nodes, weights = range_nodes if range_nodes is not None else (np.zeros(1), np.ones(1))
    theta = np.deg2rad(scan_angle_deg)
    beams = list(coefficients)
    vectors = {b: dbs_beam_unit_vector(b, scan_angle_deg) for b in beams}
    centre = {b: vectors[b] * (height_m if b == "V" else height_m / np.cos(theta)) for b in beams}
    total = 0.0
    for k in beams:
        for m in beams:
            sep = centre[m] - centre[k] - np.asarray(mean_wind) * (beam_time_s[m] - beam_time_s[k])
            # every pair of nodes: r = sep + s' s_m - s s_k
            r = (
                sep[None, None, :]
                + nodes[None, :, None] * vectors[m][None, None, :]
                - nodes[:, None, None] * vectors[k][None, None, :]
            )
            tensor = correlation_tensor(r, 1.0, integral_scale_m, "von_karman")
            proj = np.einsum("i,abij,j->ab", vectors[k], tensor, vectors[m])
            total += coefficients[k] * coefficients[m] * float(weights @ proj @ weights)
    return total


def range_nodes(delta_p_m: float, delta_r_m: float, step_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (m from the gate centre) and weights (sum 1) of the pulsed range weighting
    (:func:`cwproc.physics.two_beam.pulsed_weighting`), out to 3 ``Delta_p`` past the
    range window."""
    half = delta_r_m / 2 + 3.0 * delta_p_m
    n = int(np.ceil(half / step_m))
    s = np.arange(-n, n + 1) * step_m
    w = pulsed_weighting(s, delta_p_m, delta_r_m)
    return s, w / w.sum()


def noise_variance(
    coefficients: Mapping[str, float], noise_variances: Mapping[str, np.ndarray]
) -> np.ndarray:
    """Variance (m2 s-2) the white noise of the beams adds to a DBS estimate:
    ``sum_k a_k^2 sigma_e,k^2`` (noise independent between lines of sight)."""
    return sum(a * a * np.asarray(noise_variances[k]) for k, a in coefficients.items())
