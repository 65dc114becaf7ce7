"""Geometry of conical (VAD) scanning: beam direction, heights, scan circle, sampling.

Smalikho (2020), eqs. 3 and 6-8, with azimuth ``theta`` measured clockwise from north
and elevation ``phi`` above the horizon. Components are returned in the order
(east, north, up) = (u, v, w), so that the radial velocity (positive away from the
lidar) is

.. math:: V_r = \\mathbf{S}\\cdot\\mathbf{V}
              = w \\sin\\phi + \\cos\\phi (u \\sin\\theta + v \\cos\\theta).

(Smalikho (2020), eq. 8 writes the same with x along ``theta = 0``.)
All functions are pure and broadcast over numpy arrays; angles are in degrees.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def normalise_pointing(
    azimuth_deg: ArrayLike, elevation_deg: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Rewrite over-the-zenith pointing (elevation > 90 deg) as azimuth+180, 180-elevation.

    Halo scanners write the same direction either way (an elevation of ``180.01`` is
    azimuth + 180 deg at elevation ``-0.01``); the result has elevation in [-90, 90] deg
    and azimuth in [0, 360) deg. Signed zeros become +0 (``-0.00`` -> 0), and an azimuth
    that rounds to 360 (``360.00``, or ``-1e-17 mod 360``) becomes 0, never 360, so
    equal directions compare equal and sort together.

    Parameters
    ----------
    azimuth_deg, elevation_deg : array_like
        Pointing angles (deg), azimuth clockwise from north, elevation above the horizon.

    Returns
    -------
    (azimuth_deg, elevation_deg) : tuple of ndarray
        Broadcast shape of the inputs (deg).
    """
    az = np.asarray(azimuth_deg, dtype=float)
    el = np.asarray(elevation_deg, dtype=float)
    over = el > 90.0
    az = np.mod(np.where(over, az + 180.0, az), 360.0) + 0.0
    az = np.where(az >= 360.0, az - 360.0, az) + 0.0
    el = np.where(over, 180.0 - el, el) + 0.0
    return az, el


def beam_unit_vector(azimuth_deg: ArrayLike, elevation_deg: ArrayLike) -> FloatArray:
    """Unit vector S of the beam in (east, north, up) components.

    ``S = (cos(phi) sin(theta), cos(phi) cos(theta), sin(phi))``, Smalikho (2020),
    eq. 6 (r_c = R S(theta)) and eq. 8 (V_r = S . V).

    Parameters
    ----------
    azimuth_deg : array_like
        Azimuth theta, clockwise from north (deg).
    elevation_deg : array_like
        Elevation phi above the horizon (deg).

    Returns
    -------
    ndarray, shape (..., 3)
        Broadcast shape of the inputs plus a last axis of length 3 (dimensionless).
    """
    theta = np.deg2rad(np.asarray(azimuth_deg, dtype=float))
    phi = np.deg2rad(np.asarray(elevation_deg, dtype=float))
    theta, phi = np.broadcast_arrays(theta, phi)
    return np.stack(
        [np.cos(phi) * np.sin(theta), np.cos(phi) * np.cos(theta), np.sin(phi)], axis=-1
    )


def beam_unit_vector_une(azimuth_deg: ArrayLike, elevation_deg: ArrayLike) -> FloatArray:
    """Unit vector S of the beam in the (up, north, east) order of Banakh et al. (1999).

    ``S = (sin phi, cos phi cos theta, cos phi sin theta)``, Banakh et al. (1999), eq. 1,
    with ``theta`` clockwise from north: the components of :func:`beam_unit_vector`
    (east, north, up), reversed, as the correlation models of
    :mod:`cwproc.physics.correlation` and :mod:`cwproc.physics.two_beam` use them.

    Returns
    -------
    ndarray, shape (..., 3)
        Broadcast shape of the inputs plus a last axis of length 3 (dimensionless),
        C-contiguous.
    """
    return np.ascontiguousarray(beam_unit_vector(azimuth_deg, elevation_deg)[..., ::-1])


def radial_velocity(
    u: ArrayLike, v: ArrayLike, w: ArrayLike, azimuth_deg: ArrayLike, elevation_deg: ArrayLike
) -> FloatArray:
    """Projection of the wind on the beam, positive away from the lidar.

    ``V_r = w sin(phi) + cos(phi) (u sin(theta) + v cos(theta))``,
    Smalikho (2020), eq. 8; Smalikho (2020), eq. 1 (VAD model).

    Parameters
    ----------
    u, v, w : array_like
        Eastward, northward and upward wind (m s-1).
    azimuth_deg : array_like
        Azimuth, clockwise from north (deg).
    elevation_deg : array_like
        Elevation (deg).

    Returns
    -------
    ndarray
        Radial velocity (m s-1), broadcast shape of the inputs.
    """
    theta = np.deg2rad(np.asarray(azimuth_deg, dtype=float))
    phi = np.deg2rad(np.asarray(elevation_deg, dtype=float))
    return np.asarray(w) * np.sin(phi) + np.cos(phi) * (
        np.asarray(u) * np.sin(theta) + np.asarray(v) * np.cos(theta)
    )


def wind_components(speed: ArrayLike, direction_deg: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Eastward and northward wind of a horizontal wind blowing *from* ``direction_deg``.

    ``u = -U sin(D)``, ``v = -U cos(D)`` with D the meteorological wind-from direction
    (deg clockwise from north): a wind from 270 deg (west) has u = +U, v = 0, one from
    180 deg (south) u = 0, v = +U. Inverse of :func:`speed_and_direction`.

    Parameters
    ----------
    speed : array_like
        Horizontal wind speed U (m s-1).
    direction_deg : array_like
        Direction the wind blows from (deg clockwise from north).

    Returns
    -------
    (u, v) : tuple of ndarray
        Eastward and northward components (m s-1), broadcast shape of the inputs.
    """
    speed = np.asarray(speed, dtype=float)
    d = np.deg2rad(direction_deg)
    return -speed * np.sin(d), -speed * np.cos(d)


def speed_and_direction(u: ArrayLike, v: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Horizontal speed ``hypot(u, v)`` and wind-from direction ``atan2(-u, -v)``.

    Inverse of :func:`wind_components`; the direction is in [0, 360) deg clockwise from
    north, the direction the wind blows *from*.

    Parameters
    ----------
    u, v : array_like
        Eastward and northward wind (m s-1).

    Returns
    -------
    (speed, direction_deg) : tuple of ndarray
        Speed (m s-1) and wind-from direction (deg), broadcast shape of the inputs.
    """
    u = np.asarray(u)
    v = np.asarray(v)
    return np.hypot(u, v), np.rad2deg(np.arctan2(-u, -v)) % 360.0


def height_from_range(range_m: ArrayLike, elevation_deg: ArrayLike) -> FloatArray:
    """Height of a gate above the instrument, ``h = R sin(phi)`` (m).

    Smalikho (2020), eq. 6 (the z component of r_c = R S).

    Parameters
    ----------
    range_m : array_like
        Distance along the beam (m).
    elevation_deg : array_like
        Elevation (deg).

    Returns
    -------
    ndarray
        Height (m).
    """
    return np.asarray(range_m, dtype=float) * np.sin(np.deg2rad(elevation_deg))


def scan_circle_radius(height_m: ArrayLike, elevation_deg: ArrayLike) -> FloatArray:
    """Radius of the scan circle at height h, ``R' = h / tan(phi)`` (m).

    Smalikho (2020), eq. 7 (the horizontal circle of radius R' swept by r_c).

    Parameters
    ----------
    height_m : array_like
        Height above the instrument (m).
    elevation_deg : array_like
        Elevation (deg), 0 < phi < 90.

    Returns
    -------
    ndarray
        R' (m).
    """
    return np.asarray(height_m, dtype=float) / np.tan(np.deg2rad(elevation_deg))


def linear_scan_speed(
    height_m: ArrayLike, elevation_deg: ArrayLike, scan_period_s: ArrayLike
) -> FloatArray:
    """Linear speed of the probe volume on the scan circle, ``V_s = 2 pi h / (T tan phi)``.

    Smalikho (2020), eq. 3.

    Parameters
    ----------
    height_m : array_like
        Height (m).
    elevation_deg : array_like
        Elevation (deg).
    scan_period_s : array_like
        Duration T_scan of one 360 deg rotation (s).

    Returns
    -------
    ndarray
        V_s (m s-1).
    """
    return (
        2.0
        * np.pi
        * scan_circle_radius(height_m, elevation_deg)
        / np.asarray(scan_period_s, dtype=float)
    )


def transverse_sampling(azimuth_step_deg: ArrayLike, radius_m: ArrayLike) -> FloatArray:
    """Arc length between neighbouring rays on the scan circle, ``dy = dtheta R'`` (m).

    Smalikho (2020), eq. 7 and the definition of Delta y before eq. 15.

    Parameters
    ----------
    azimuth_step_deg : array_like
        Azimuth step dtheta between rays (deg).
    radius_m : array_like
        Scan-circle radius R' (m).

    Returns
    -------
    ndarray
        dy (m).
    """
    return np.deg2rad(np.asarray(azimuth_step_deg, dtype=float)) * np.asarray(radius_m, dtype=float)
