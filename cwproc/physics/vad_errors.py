"""Error theory of the least-squares VAD wind fit, reconstructed.

The paper (:data:`cwproc.references.VAD_ACCURACY`, "the paper" below) states its results
in prose; its formulas were lost from the text, and are re-derived here from the prose
and the surrounding equations (the prose values, e.g. 11 % growth of the along-bisector
error for a missing sector, are tests).

Convention (the paper, section 2): a right-handed frame with x and y horizontal and z
up; a ray at elevation ``phi`` and azimuth ``theta`` (counted from the x axis towards
y) measures

.. math:: V_r = V_x \\cos\\phi \\cos\\theta + V_y \\cos\\phi \\sin\\theta + V_z \\sin\\phi .

With azimuths from north (``cwproc.stages.vad``) x is north and y is east, so
``(V_x, V_y, V_z) = (v, u, w)``. Every function returns the three components in the
order ``(V_x, V_y, V_z)``. Angles are in degrees.

Two estimators are covered:

* the **decoupled estimator** of the paper, eq. 4: each component from its own
  trigonometric sum, ``V_x = sum(V_r cos) / (cos(phi) sum(cos^2))``,
  ``V_y = sum(V_r sin) / (cos(phi) sum(sin^2))``, ``V_z = sum(V_r) / (n sin(phi))``.
  It is the least-squares solution for a full circle of uniformly spaced azimuths
  (N >= 3) and the estimator the paper analyses for a missing sector;
* the **true least squares** ``(A^T A)^-1 A^T V_r``, which is what ``fit_vad`` uses.
  With a missing sector ``sum(cos) != 0`` and V_x, V_z couple, so the true LS errors
  differ from the paper's.

A radial error model is either a bound ``|d_i| <= bound`` (maximum error: the
worst case ``d_i = bound * sign(weight_i)`` gives ``bound * sum|weight_i|``, the paper,
eqs. 6, 13) or independent Gaussian errors of standard deviation ``sigma``
(RMS error ``sigma * sqrt(sum weight_i^2)``, the paper, section 4).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cwproc.physics.geometry import beam_unit_vector, height_from_range

FloatArray = NDArray[np.float64]


# --------------------------------------------------------------------------------------
# azimuth sets and estimators
# --------------------------------------------------------------------------------------


def uniform_azimuths_deg(n_azimuths: int, sector_deg: float = 0.0) -> FloatArray:
    """Uniformly spaced azimuths ``360 i / N`` (deg) with a missing sector removed.

    Parameters
    ----------
    n_azimuths : int
        Number of azimuths N of the full circle (the paper, section 2: uniform spacing).
    sector_deg : float, optional
        Full width s (deg) of a missing sector centred on the x axis: azimuths with
        ``|theta| < s/2`` are removed (the paper, section 5).

    Returns
    -------
    ndarray
        The kept azimuths (deg, from the x axis), in increasing order of ``360 i/N``.
    """
    if n_azimuths < 1:
        raise ValueError("n_azimuths must be >= 1")
    theta = 360.0 * np.arange(n_azimuths) / n_azimuths
    centred = (theta + 180.0) % 360.0 - 180.0
    keep = np.abs(centred) >= sector_deg / 2.0 - 1e-9 * max(sector_deg, 1.0)
    if sector_deg <= 0:
        keep[:] = True
    return theta[keep]


def design_matrix(azimuth_deg: ArrayLike, phi_deg: float) -> FloatArray:
    """Rows ``(cos(phi) cos(theta), cos(phi) sin(theta), sin(phi))`` of the VAD model.

    The paper, section 2 (projection of the wind on the beam); Smalikho (2020), eq. 8.
    These are the beam unit vectors of :func:`cwproc.physics.geometry.beam_unit_vector`
    (east, north, up) with x = north and y = east, i.e. reordered to the paper's
    ``(V_x, V_y, V_z) = (v, u, w)``.

    Parameters
    ----------
    azimuth_deg : array_like
        Azimuths theta (deg, from the x axis).
    phi_deg : float
        Elevation (deg).

    Returns
    -------
    ndarray, shape (n, 3)
    """
    east_north_up = beam_unit_vector(np.asarray(azimuth_deg, dtype=float), phi_deg)
    return np.ascontiguousarray(east_north_up[..., [1, 0, 2]])


def least_squares_weights(azimuth_deg: ArrayLike, phi_deg: float) -> FloatArray:
    """Weights ``W = (A^T A)^-1 A^T`` of the true least-squares VAD fit.

    The error of the fitted wind is ``W d`` for radial errors ``d`` (the paper, eq. 5).

    Parameters
    ----------
    azimuth_deg : array_like
        Azimuths (deg, from the x axis); at least three distinct ones.
    phi_deg : float
        Elevation (deg).

    Returns
    -------
    ndarray, shape (3, n)
    """
    a = design_matrix(azimuth_deg, phi_deg)
    return np.linalg.solve(a.T @ a, a.T)


def decoupled_weights(azimuth_deg: ArrayLike, phi_deg: float) -> FloatArray:
    """Weights of the decoupled estimator of the paper, eq. 4 (and section 5).

    ``V_x = sum(V_r cos th) / (cos phi sum cos^2 th)``,
    ``V_y = sum(V_r sin th) / (cos phi sum sin^2 th)``,
    ``V_z = sum(V_r) / (n sin phi)``.

    Parameters
    ----------
    azimuth_deg : array_like
        Azimuths (deg, from the x axis).
    phi_deg : float
        Elevation (deg).

    Returns
    -------
    ndarray, shape (3, n)
    """
    theta = np.deg2rad(np.asarray(azimuth_deg, dtype=float))
    phi = np.deg2rad(phi_deg)
    c, s = np.cos(theta), np.sin(theta)
    return np.stack(
        [
            c / (np.cos(phi) * np.sum(c**2)),
            s / (np.cos(phi) * np.sum(s**2)),
            np.full_like(theta, 1.0 / (theta.size * np.sin(phi))),
        ]
    )


def max_errors(weights: ArrayLike, bound: float) -> FloatArray:
    """Maximum errors ``bound * sum_i |W_ki|`` of the three components.

    The paper, eqs. 6a-6c (full circle) and 13 (missing sector): the bound is attained
    by ``d_i = bound * sign(W_ki)``.

    Parameters
    ----------
    weights : array_like, shape (3, n)
        Estimator weights (:func:`least_squares_weights`, :func:`decoupled_weights`).
    bound : float
        Bound Delta of the radial-velocity error (m s-1).

    Returns
    -------
    ndarray, shape (3,)
        Maximum errors of (V_x, V_y, V_z) (m s-1).
    """
    return bound * np.sum(np.abs(np.asarray(weights, dtype=float)), axis=-1)


def rms_errors(weights: ArrayLike, sigma: float) -> FloatArray:
    """RMS errors ``sigma * sqrt(sum_i W_ki^2)`` for independent radial errors.

    The paper, section 4 (weighted sums of independent Gaussian errors).

    Parameters
    ----------
    weights : array_like, shape (3, n)
        Estimator weights.
    sigma : float
        Standard deviation of the radial-velocity error (m s-1).

    Returns
    -------
    ndarray, shape (3,)
        RMS errors of (V_x, V_y, V_z) (m s-1).
    """
    return sigma * np.sqrt(np.sum(np.asarray(weights, dtype=float) ** 2, axis=-1))


# --------------------------------------------------------------------------------------
# closed forms: full circle
# --------------------------------------------------------------------------------------


def max_error_full_circle(n_azimuths: int, phi_deg: float, bound: float) -> FloatArray:
    """Maximum errors for N uniform azimuths (the paper, eqs. 6a-6c), closed sums.

    ``max|dV_x| = 2 bound sum|cos th_i| / (N cos phi)``, the same with ``|sin|`` for
    V_y, and ``max|dV_z| = bound / sin phi`` (independent of N).

    Parameters
    ----------
    n_azimuths : int
        N >= 3.
    phi_deg : float
        Elevation (deg).
    bound : float
        Radial error bound (m s-1).

    Returns
    -------
    ndarray, shape (3,)
    """
    theta = 2.0 * np.pi * np.arange(n_azimuths) / n_azimuths
    phi = np.deg2rad(phi_deg)
    factor = 2.0 * bound / (n_azimuths * np.cos(phi))
    return np.array(
        [
            factor * np.sum(np.abs(np.cos(theta))),
            factor * np.sum(np.abs(np.sin(theta))),
            bound / np.sin(phi),
        ]
    )


def max_error_full_circle_limit(phi_deg: float, bound: float) -> FloatArray:
    """Limit N -> infinity of the maximum errors (the paper, eq. 12).

    ``max|dV_x| = max|dV_y| = 4 bound / (pi cos phi)``, ``max|dV_z| = bound / sin phi``.

    Parameters
    ----------
    phi_deg : float
        Elevation (deg).
    bound : float
        Radial error bound (m s-1).

    Returns
    -------
    ndarray, shape (3,)
    """
    phi = np.deg2rad(phi_deg)
    horizontal = 4.0 * bound / (np.pi * np.cos(phi))
    return np.array([horizontal, horizontal, bound / np.sin(phi)])


def rms_error_full_circle(n_azimuths: int, phi_deg: float, sigma: float) -> FloatArray:
    """RMS errors for N >= 3 uniform azimuths (the paper, section 4), exact.

    ``rms dV_x = rms dV_y = sigma sqrt(2/N) / cos phi``,
    ``rms dV_z = sigma / (sqrt(N) sin phi)``.

    Parameters
    ----------
    n_azimuths : int
        N >= 3.
    phi_deg : float
        Elevation (deg).
    sigma : float
        Radial error standard deviation (m s-1).

    Returns
    -------
    ndarray, shape (3,)
    """
    if n_azimuths < 3:
        raise ValueError("the closed form needs N >= 3 uniform azimuths")
    phi = np.deg2rad(phi_deg)
    horizontal = sigma * np.sqrt(2.0 / n_azimuths) / np.cos(phi)
    return np.array([horizontal, horizontal, sigma / (np.sqrt(n_azimuths) * np.sin(phi))])


# --------------------------------------------------------------------------------------
# closed forms: missing sector (decoupled estimator)
# --------------------------------------------------------------------------------------


def max_error_sector_asymptotic(phi_deg: float, sector_deg: float, bound: float) -> FloatArray:
    """Maximum errors of the decoupled estimator with a missing sector, N -> infinity.

    The paper, eq. 15 (sums replaced by integrals over the kept azimuths
    ``alpha <= theta <= 2 pi - alpha``, ``alpha = s/2 <= pi/2``):

    ``max|dV_x| = bound (4 - 2 sin a) / (cos phi (pi - a - sin(2a)/2))``,
    ``max|dV_y| = bound (2 + 2 cos a) / (cos phi (pi - a + sin(2a)/2))``,
    ``max|dV_z| = bound / sin phi``.

    Parameters
    ----------
    phi_deg : float
        Elevation (deg).
    sector_deg : float
        Full width s of the missing sector (deg), 0 <= s <= 180; centred on x.
    bound : float
        Radial error bound (m s-1).

    Returns
    -------
    ndarray, shape (3,)
    """
    if not 0.0 <= sector_deg <= 180.0:
        raise ValueError("sector_deg must be in [0, 180]")
    a = np.deg2rad(sector_deg) / 2.0
    phi = np.deg2rad(phi_deg)
    dvx = (4.0 - 2.0 * np.sin(a)) / (np.pi - a - np.sin(2.0 * a) / 2.0)
    dvy = (2.0 + 2.0 * np.cos(a)) / (np.pi - a + np.sin(2.0 * a) / 2.0)
    return np.array([bound * dvx / np.cos(phi), bound * dvy / np.cos(phi), bound / np.sin(phi)])


def sector_error_factor(sector_deg: ArrayLike) -> FloatArray:
    """Growth factor of the along-bisector maximum error, small sector (the paper, eq. 16).

    Linearising eq. 15 in ``alpha = s/2`` (sin a ~ a, sin 2a ~ 2a, dropping a^2):
    ``k(s) = 1 + (2/pi - 1/2) s/2``; ``k(90 deg) = 1.107``, the "about 11 %" of the
    paper. The across-bisector error is unchanged to first order.

    Parameters
    ----------
    sector_deg : array_like
        Full width of the missing sector (deg).

    Returns
    -------
    ndarray
        Dimensionless factor multiplying ``4 bound / (pi cos phi)``.
    """
    a = np.deg2rad(np.asarray(sector_deg, dtype=float)) / 2.0
    return 1.0 + (2.0 / np.pi - 0.5) * a


def max_error_sector_linearised(phi_deg: float, sector_deg: float, bound: float) -> FloatArray:
    """The paper, eq. 16: small-sector maximum errors of the decoupled estimator.

    ``max|dV_x| = k(s) 4 bound / (pi cos phi)`` (:func:`sector_error_factor`),
    ``max|dV_y| = 4 bound / (pi cos phi)``, ``max|dV_z| = bound / sin phi``.

    Parameters
    ----------
    phi_deg : float
        Elevation (deg).
    sector_deg : float
        Full width of the missing sector (deg).
    bound : float
        Radial error bound (m s-1).

    Returns
    -------
    ndarray, shape (3,)
    """
    full = max_error_full_circle_limit(phi_deg, bound)
    return np.array([full[0] * float(sector_error_factor(sector_deg)), full[1], full[2]])


# --------------------------------------------------------------------------------------
# linear horizontal gradient
# --------------------------------------------------------------------------------------


def shear_radial_error(
    azimuth_deg: ArrayLike, phi_deg: float, radius_m: float, dvx_dx: float, dvy_dx: float
) -> FloatArray:
    """Extra radial velocity of a linear horizontal gradient along x (the paper, eq. 18).

    With ``V_x = V_x0 + a x``, ``V_y = V_y0 + b x`` and the measurement points at
    ``x_i = R' cos th_i``: ``d_i = R' cos phi (a cos^2 th_i + b cos th_i sin th_i)``.

    Parameters
    ----------
    azimuth_deg : array_like
        Azimuths (deg, from x).
    phi_deg : float
        Elevation (deg).
    radius_m : float
        Scan-circle radius R' = h / tan(phi) (m), Smalikho (2020), eq. 6.
    dvx_dx, dvy_dx : float
        Gradients a = dV_x/dx and b = dV_y/dx (s-1).

    Returns
    -------
    ndarray
        d_i (m s-1).
    """
    theta = np.deg2rad(np.asarray(azimuth_deg, dtype=float))
    phi = np.deg2rad(phi_deg)
    c, s = np.cos(theta), np.sin(theta)
    return radius_m * np.cos(phi) * (dvx_dx * c**2 + dvy_dx * c * s)


def shear_bias(
    azimuth_deg: ArrayLike,
    phi_deg: float,
    radius_m: float,
    dvx_dx: float,
    dvy_dx: float,
    *,
    estimator: str = "least_squares",
) -> FloatArray:
    """Bias of the fitted mean wind caused by a linear horizontal gradient (the paper, eq. 19).

    For N >= 4 uniform azimuths only V_z is biased, by :func:`shear_w_bias`; N = 3 also
    biases the horizontal components (``sum cos^3 th_i != 0``).

    Parameters
    ----------
    azimuth_deg : array_like
        Azimuths (deg, from x).
    phi_deg : float
        Elevation (deg).
    radius_m : float
        Scan-circle radius R' (m).
    dvx_dx, dvy_dx : float
        Gradients along x (s-1).
    estimator : {"least_squares", "decoupled"}
        Which estimator.

    Returns
    -------
    ndarray, shape (3,)
        Biases of (V_x, V_y, V_z) (m s-1).
    """
    weights = _weights(azimuth_deg, phi_deg, estimator)
    return weights @ shear_radial_error(azimuth_deg, phi_deg, radius_m, dvx_dx, dvy_dx)


def shear_w_bias(phi_deg: float, radius_m: ArrayLike, dvx_dx: float) -> FloatArray:
    """Bias of V_z from the divergence of a gradient along x: ``a R' / (2 tan phi)``.

    The paper, eq. 22 (N >= 4 uniform azimuths; exact, not only a bound).

    Parameters
    ----------
    phi_deg : float
        Elevation (deg).
    radius_m : array_like
        Scan-circle radius R' (m).
    dvx_dx : float
        Gradient a = dV_x/dx (s-1).

    Returns
    -------
    ndarray
        Bias of V_z (m s-1).
    """
    return dvx_dx * np.asarray(radius_m, dtype=float) / (2.0 * np.tan(np.deg2rad(phi_deg)))


def shear_error_bound(
    azimuth_deg: ArrayLike, phi_deg: float, radius_m: float, dvx_dx: float, dvy_dx: float
) -> FloatArray:
    """Triangle-inequality bound of the gradient error, finite N (the paper, eqs. 20a-20c).

    The gradient term is treated as an extra bounded radial error
    ``|d_i| <= R' cos phi (|a| cos^2 th_i + |b| |cos th_i sin th_i|)`` of the decoupled
    estimator: ``|dV_k| <= sum_i |W_ki| |d_i|``.

    Parameters
    ----------
    azimuth_deg : array_like
        Azimuths (deg, from x).
    phi_deg : float
        Elevation (deg).
    radius_m : float
        Scan-circle radius R' (m).
    dvx_dx, dvy_dx : float
        Gradients along x (s-1).

    Returns
    -------
    ndarray, shape (3,)
        Bounds for (V_x, V_y, V_z) (m s-1).
    """
    theta = np.deg2rad(np.asarray(azimuth_deg, dtype=float))
    phi = np.deg2rad(phi_deg)
    c, s = np.cos(theta), np.sin(theta)
    d_abs = radius_m * np.cos(phi) * (abs(dvx_dx) * c**2 + abs(dvy_dx) * np.abs(c * s))
    return np.abs(decoupled_weights(azimuth_deg, phi_deg)) @ d_abs


def shear_error_bound_limit(
    phi_deg: float, radius_m: float, dvx_dx: float, dvy_dx: float
) -> FloatArray:
    """Limit N -> infinity of :func:`shear_error_bound` (the paper, eq. 23).

    ``|dV_x| <= (R'/pi)(8|a|/3 + 4|b|/3)``, ``|dV_y| <= (R'/pi)(4|a|/3 + 4|b|/3)``,
    ``|dV_z| <= (R'/tan phi)(|a|/2 + |b|/pi)``.

    Parameters
    ----------
    phi_deg : float
        Elevation (deg).
    radius_m : float
        Scan-circle radius R' (m).
    dvx_dx, dvy_dx : float
        Gradients along x (s-1).

    Returns
    -------
    ndarray, shape (3,)
    """
    a, b = abs(dvx_dx), abs(dvy_dx)
    tan_phi = np.tan(np.deg2rad(phi_deg))
    return np.array(
        [
            radius_m / np.pi * (8.0 * a / 3.0 + 4.0 * b / 3.0),
            radius_m / np.pi * (4.0 * a / 3.0 + 4.0 * b / 3.0),
            radius_m / tan_phi * (a / 2.0 + b / np.pi),
        ]
    )


# --------------------------------------------------------------------------------------
# tilted cone axis
# --------------------------------------------------------------------------------------


def tilt_bias_first_order(
    phi_deg: float,
    tilt_deg: float,
    vx: float,
    vz: float,
    dvx_dz: float,
    radius_m: float,
) -> FloatArray:
    """First-order bias of a cone axis tilted by gamma towards +x (the paper, eq. 24).

    ``dV_x = -gamma V_z``, ``dV_y = 0``,
    ``dV_z = gamma V_x - gamma (dV_x/dz) R' / (2 tan phi)``: the tilt projects V_x on
    the vertical, and the ray heights ``z_i - h = -R' gamma cos th_i`` turn a vertical
    shear into a horizontal gradient ``a = -gamma dV_x/dz`` (:func:`shear_w_bias`).

    Parameters
    ----------
    phi_deg : float
        Elevation (deg).
    tilt_deg : float
        Tilt gamma of the cone axis from the vertical, towards +x (deg).
    vx, vz : float
        Wind components along x and z (m s-1).
    dvx_dz : float
        Vertical shear of V_x (s-1).
    radius_m : float
        Scan-circle radius R' (m).

    Returns
    -------
    ndarray, shape (3,)
    """
    gamma = np.deg2rad(tilt_deg)
    return np.array(
        [
            -gamma * vz,
            0.0,
            gamma * vx - gamma * float(shear_w_bias(phi_deg, radius_m, dvx_dz)),
        ]
    )


def tilt_bias_exact(
    phi_deg: float,
    tilt_deg: float,
    wind: ArrayLike,
    dvx_dz: float,
    range_m: float,
    n_azimuths: int,
) -> FloatArray:
    """Exact bias of the least-squares fit with a cone axis tilted towards +x.

    The beams are the nominal beams rotated by gamma about the y axis; each ray
    samples ``V = (V_x + (dV_x/dz)(z_i - R sin phi), V_y, V_z)`` at its true height
    ``z_i``; the fit assumes the nominal geometry. This is the model behind the paper,
    eq. 24 without the linearisation.

    Parameters
    ----------
    phi_deg : float
        Elevation (deg).
    tilt_deg : float
        Tilt gamma (deg).
    wind : array_like, shape (3,)
        (V_x, V_y, V_z) at the nominal height R sin(phi) (m s-1).
    dvx_dz : float
        Vertical shear of V_x (s-1).
    range_m : float
        Range R along the beam (m).
    n_azimuths : int
        Number of uniformly spaced azimuths.

    Returns
    -------
    ndarray, shape (3,)
        Fitted minus true (V_x, V_y, V_z) (m s-1).
    """
    wind = np.asarray(wind, dtype=float)
    theta = uniform_azimuths_deg(n_azimuths)
    nominal = design_matrix(theta, phi_deg)
    gamma = np.deg2rad(tilt_deg)
    rotation = np.array(
        [
            [np.cos(gamma), 0.0, np.sin(gamma)],
            [0.0, 1.0, 0.0],
            [-np.sin(gamma), 0.0, np.cos(gamma)],
        ]
    )
    beams = nominal @ rotation.T
    heights = range_m * beams[:, 2]
    local = np.tile(wind, (theta.size, 1))
    local[:, 0] += dvx_dz * (heights - height_from_range(range_m, phi_deg))
    radial = np.sum(beams * local, axis=1)
    fitted = np.linalg.lstsq(nominal, radial, rcond=None)[0]
    return fitted - wind


def _weights(azimuth_deg: ArrayLike, phi_deg: float, estimator: str) -> FloatArray:
    if estimator == "least_squares":
        return least_squares_weights(azimuth_deg, phi_deg)
    if estimator == "decoupled":
        return decoupled_weights(azimuth_deg, phi_deg)
    raise ValueError(f"estimator must be 'least_squares' or 'decoupled', got {estimator!r}")
