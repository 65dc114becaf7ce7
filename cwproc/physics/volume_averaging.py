"""Volume averaging of a conically scanning cw lidar (ZephIR): Wagner et al. (DTU).

A ZephIR measures the wind at height ``h`` by focusing a cw beam, tilted 30 degrees
from the vertical, at the range ``R = h / cos 30°`` and turning it once per second
around the vertical (50 line-of-sight estimates per rotation). Its horizontal wind
is a cosine fit over one (1-s scan) or three (3-s scan) rotations. Two averaging
steps filter the turbulence it sees (Wagner et al. (DTU), sect. 2):

1. along the beam, the Lorentzian weighting of the probe volume,
   Wagner et al. (DTU), eqs. 2-3, with ``Z_R = 0.0013 R**2``;
2. around the scan circle, the least-squares fit over the rotation(s), while the
   wind carries the turbulence through the circle, Wagner et al. (DTU), eqs. 4-7.

The 10-min standard deviation of the lidar's horizontal speed is then the Kaimal
spectrum (Wagner et al. (DTU), eq. 9) filtered by both (eq. 11), divided by the
unfiltered one (eq. 10) for a cup. The turbulence parameter TP carries the part of
the spectrum the scan filter removes but the probe volume keeps (eqs. 12-13).

Wavenumbers ``k`` are in cycles per metre throughout (``cos(2 pi k x)`` kernels).

The scan filter (the formulas of Wagner et al. (DTU), eqs. 4-7, were lost in the
text extraction; re-derived here, see ``docs/zephir.md``)
--------------------------------------------------------------------------------
Take the mean wind ``U`` along ``x``. In the frame that moves with the air (Taylor's
frozen turbulence), the focus at time ``t`` of the scan sits at
``x(t) = r cos(2 pi t / T_rot) - U t``, ``y(t) = r sin(2 pi t / T_rot)``, with the scan
radius ``r = h tan 30°`` (Wagner et al. (DTU), Fig. 3). The air seen by one wind vector
is the strip swept by a circle of diameter ``D = 2 r`` that moves ``U T_scan`` during
the scan ("the distance covered by a circle of diameter D moving with the mean wind
U", sect. 2.2), so the effective horizontal averaging length of eq. 4 is

    l_az = 2 h tan 30° + U T_scan.

The cosine fit weights each line of sight by the coefficient function of the
component it estimates (``cos²`` of the azimuth along the wind, eq. 5; ``sin²``
across, eq. 6; uniform for ``w``, eq. 7). Laid out over ``l_az`` and transformed,
these give the closed-form transfer functions of :func:`scan_transfer`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from cwproc.physics.constants import ZEPHIR_Z_R_COEFFICIENT

#: half-opening angle of the ZephIR scan cone, from the vertical (deg), Wagner et al. (DTU)
CONE_HALF_ANGLE_DEG = 30.0
#: line-of-sight estimates per rotation, Wagner et al. (DTU), sect. 2.2
SAMPLES_PER_ROTATION = 50
#: duration of one rotation (s), Wagner et al. (DTU), sect. 2.2
ROTATION_PERIOD_S = 1.0
#: Kaimal (1972) neutral surface-layer constants: n S_u / u*² = A f / (1 + B f)^(5/3)
KAIMAL_A = 105.0
KAIMAL_B = 33.0

FloatArray = npt.NDArray[np.float64]


def focus_range(height: npt.ArrayLike, cone_half_angle_deg: float = CONE_HALF_ANGLE_DEG):
    """Focus distance of the beam for a measurement height.

    Parameters
    ----------
    height : array_like
        Height above the lidar window (m).
    cone_half_angle_deg : float
        Angle of the beam from the vertical (deg); 30 for ZephIR.

    Returns
    -------
    ndarray
        ``R = h / cos(30°)`` (m), Wagner et al. (DTU), sect. 2.2.
    """
    return np.asarray(height, dtype=float) / np.cos(np.radians(cone_half_angle_deg))


def zephir_rayleigh_range(
    height: npt.ArrayLike,
    z_r_coefficient: float = ZEPHIR_Z_R_COEFFICIENT,
    cone_half_angle_deg: float = CONE_HALF_ANGLE_DEG,
):
    """Half width of the Lorentzian probe weighting, ``Z_R = c R²``.

    Parameters
    ----------
    height : array_like
        Height above the lidar window (m).
    z_r_coefficient : float
        ``c`` (1/m); ZephIR 0.0013, Wagner et al. (DTU), eq. 2.
    cone_half_angle_deg : float
        Angle of the beam from the vertical (deg).

    Returns
    -------
    ndarray
        ``Z_R`` (m).
    """
    return z_r_coefficient * focus_range(height, cone_half_angle_deg) ** 2


def kaimal_spectrum(k: npt.ArrayLike, height: float, u_star: float = 1.0) -> FloatArray:
    """One-sided Kaimal spectrum of the along-wind velocity in wavenumber space.

    .. math:: F_u(k) = \\frac{105\\, z\\, u_*^2}{(1 + 33\\, k z)^{5/3}}

    from ``n S_u(n) / u*² = 105 f / (1 + 33 f)^(5/3)``, ``f = n z / U``, with Taylor's
    hypothesis ``k = n / U``; Wagner et al. (DTU), eq. 9. Its integral over
    ``k`` in [0, inf) is ``105 / (33 * 2/3) u*² = 4.773 u*²`` (Wagner et al. (DTU), eq. 10).

    Parameters
    ----------
    k : array_like
        Wavenumber (cycles per metre), >= 0.
    height : float
        Height above ground (m).
    u_star : float
        Friction velocity (m s-1); ratios do not depend on it.

    Returns
    -------
    ndarray
        Spectral density (m3 s-2 per cycle).
    """
    k = np.asarray(k, dtype=float)
    return KAIMAL_A * height * u_star**2 / (1.0 + KAIMAL_B * k * height) ** (5.0 / 3.0)


def lorentzian_weight(s: npt.ArrayLike, z_r: float) -> FloatArray:
    """Lorentzian weighting of the cw probe volume along the beam.

    .. math:: \\varphi(s) = \\frac{1}{\\pi}\\frac{Z_R}{Z_R^2 + s^2}

    Wagner et al. (DTU), eq. 2; Banakh et al. (1999) Q_s (corrected form).

    Parameters
    ----------
    s : array_like
        Distance from the focus along the beam (m).
    z_r : float
        Half width at half maximum ``Z_R`` (m).

    Returns
    -------
    ndarray
        Weight (1/m), integrating to 1 over the real line.
    """
    s = np.asarray(s, dtype=float)
    return z_r / (np.pi * (z_r**2 + s**2))


def lorentzian_transfer(k: npt.ArrayLike, z_r: npt.ArrayLike) -> FloatArray:
    """Power transfer function of the Lorentzian probe weighting.

    The Fourier transform of :func:`lorentzian_weight` is ``exp(-2 pi Z_R |k|)``; its
    square filters the spectrum: ``|L(k)|² = exp(-4 pi Z_R |k|)``, Wagner et al. (DTU),
    eq. 3 (with ``k`` in cycles per metre).

    Parameters
    ----------
    k : array_like
        Wavenumber along the beam (cycles per metre).
    z_r : array_like
        ``Z_R`` (m), broadcast against ``k``.

    Returns
    -------
    ndarray
        Dimensionless transfer, 1 at ``k = 0``.
    """
    return np.exp(-4.0 * np.pi * np.asarray(z_r, dtype=float) * np.abs(np.asarray(k, float)))


def azimuth_length_scale(
    height: npt.ArrayLike,
    wind_speed: npt.ArrayLike,
    scan_time_s: float,
    cone_half_angle_deg: float = CONE_HALF_ANGLE_DEG,
):
    """Effective horizontal averaging length of the conical scan, ``l_az``.

    .. math:: l_{az} = 2 h \\tan 30^\\circ + U\\, T_{scan}

    Re-derivation of Wagner et al. (DTU), eq. 4 (lost in the extraction): the
    along-wind extent, in the frame moving with the air, of the focus trajectory
    ``x(t) = r cos(2 pi t/T_rot) - U t`` over the scan, to first order in
    ``U T_rot / r`` (the diameter of the scan circle plus the advection during
    the scan).

    Parameters
    ----------
    height : array_like
        Height (m).
    wind_speed : array_like
        Mean horizontal wind speed ``U`` (m s-1).
    scan_time_s : float
        Duration of the scan behind one wind vector (s): 1 or 3 for ZephIR.
    cone_half_angle_deg : float
        Angle of the beam from the vertical (deg).

    Returns
    -------
    ndarray
        ``l_az`` (m).
    """
    h = np.asarray(height, dtype=float)
    diameter = 2.0 * h * np.tan(np.radians(cone_half_angle_deg))
    return diameter + np.asarray(wind_speed, dtype=float) * scan_time_s


def scan_trajectory(
    height: float,
    wind_speed: float,
    scan_time_s: float,
    *,
    samples_per_rotation: int = SAMPLES_PER_ROTATION,
    rotation_period_s: float = ROTATION_PERIOD_S,
    cone_half_angle_deg: float = CONE_HALF_ANGLE_DEG,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Focus positions of the scan in the frame that moves with the air.

    Wagner et al. (DTU), Fig. 3: ``x = r cos(theta) - U t``, ``y = r sin(theta)``,
    ``r = h tan 30°``, ``theta = 2 pi t / T_rot``; the mean wind blows along +x. This is
    the geometry behind :func:`azimuth_length_scale`.

    Parameters
    ----------
    height : float
        Height (m).
    wind_speed : float
        Mean wind ``U`` (m s-1).
    scan_time_s : float
        Scan duration (s).
    samples_per_rotation : int
        Line-of-sight estimates per rotation (50 for ZephIR).
    rotation_period_s : float
        Duration of one rotation (s).
    cone_half_angle_deg : float
        Angle of the beam from the vertical (deg).

    Returns
    -------
    theta, x, y : ndarray
        Azimuth from the upwind direction (rad) and position (m) of each sample.
    """
    n = round(scan_time_s / rotation_period_s * samples_per_rotation)
    if n < 3:
        raise ValueError("scan_time_s: a scan needs at least 3 line-of-sight samples")
    t = (np.arange(n) + 0.5) * rotation_period_s / samples_per_rotation
    theta = 2.0 * np.pi * t / rotation_period_s
    radius = height * np.tan(np.radians(cone_half_angle_deg))
    return theta, radius * np.cos(theta) - wind_speed * t, radius * np.sin(theta)


def scan_transfer(
    k: npt.ArrayLike,
    length_scale: npt.ArrayLike,
    component: str = "along",
) -> FloatArray:
    """Power transfer function of the conical-scan averaging, ``L_scan(k)``.

    The cosine fit weights each line of sight by the coefficient function of the
    component it estimates: ``cos²`` of the azimuth from the wind for the along-wind
    speed (Wagner et al. (DTU), eq. 5, "a smoothed sine curve"), ``sin²`` across it
    (eq. 6), uniform for the vertical speed (eq. 7, a rectangle). Laid out over the
    averaging length ``l = l_az`` (one period of the azimuth per ``l``), the weights
    are ``f(x) = (1 ± cos(4 pi x / l)) / l`` and ``f(x) = 1 / l`` on ``|x| <= l/2``;
    normalised, transformed and squared (sect. 2.2) they give

    .. math::

        L_{scan}(k) = \\Big[\\mathrm{sinc}(kl) \\pm \\tfrac12\\big(\\mathrm{sinc}(kl-2)
        + \\mathrm{sinc}(kl+2)\\big)\\Big]^2,\\qquad
        L_{scan}^{(w)}(k) = \\mathrm{sinc}^2(kl)

    with ``sinc(x) = sin(pi x)/(pi x)`` and ``k`` in cycles per metre.

    Parameters
    ----------
    k : array_like
        Along-wind wavenumber (cycles per metre).
    length_scale : array_like
        ``l_az`` (m), from :func:`azimuth_length_scale`; broadcast against ``k``.
    component : {"along", "across", "vertical"}
        Which wind component.

    Returns
    -------
    ndarray
        Transfer in [0, 1], 1 at ``k = 0``.
    """
    x = np.asarray(k, dtype=float) * np.asarray(length_scale, dtype=float)
    if component == "vertical":
        return np.sinc(x) ** 2
    sign = {"along": 1.0, "across": -1.0}.get(component)
    if sign is None:
        raise ValueError(f"component: must be along, across or vertical, got {component!r}")
    return (np.sinc(x) + sign * 0.5 * (np.sinc(x - 2.0) + np.sinc(x + 2.0))) ** 2


def averaging_window_transfer(k: npt.ArrayLike, wind_speed: float, window_s: float):
    """Fraction of the spectrum seen by a standard deviation over a finite window.

    The variance about the mean of a record of length ``T`` passes
    ``1 - sinc²(pi k U T)`` of the spectrum (Taylor's hypothesis, ``k`` in cycles
    per metre); both the lidar and the cup see this 10-min high-pass.

    Parameters
    ----------
    k : array_like
        Wavenumber (cycles per metre).
    wind_speed : float
        ``U`` (m s-1).
    window_s : float
        Averaging window ``T`` (s), 600 for 10-min statistics.

    Returns
    -------
    ndarray
        Transfer in [0, 1].
    """
    return 1.0 - np.sinc(np.asarray(k, dtype=float) * wind_speed * window_s) ** 2


def _wavenumbers(height: float) -> FloatArray:
    # log-spaced from scales far beyond a 10-min window to well below the probe length
    return np.geomspace(1e-7, 20.0 / max(height, 1.0), 1500)


def _integrate_log(y: FloatArray, k: FloatArray) -> float:
    # integrate y dk on a log grid as y k d(ln k): accurate for power-law tails
    return float(np.trapezoid(y * k, np.log(k)))


def std_ratio_and_tp_share(
    height: float,
    wind_speed: float,
    scan_time_s: float,
    *,
    z_r_coefficient: float = ZEPHIR_Z_R_COEFFICIENT,
    window_s: float = 600.0,
) -> tuple[float, float]:
    """Predicted lidar/cup standard-deviation ratio and the variance share carried by TP.

    .. math::

        \\frac{\\sigma_{lidar}^2}{\\sigma_{cup}^2} =
        \\frac{\\int F_u H_T |L_{Lor}|^2 L_{scan}\\,dk}{\\int F_u H_T\\,dk},
        \\qquad
        s_{TP} = \\frac{\\int F_u |L_{Lor}|^2 (1 - L_{scan})\\,dk}{\\int F_u H_T\\,dk}

    Wagner et al. (DTU), eqs. 10-12: the Kaimal spectrum ``F_u`` (eq. 9), the
    Lorentzian probe filter (eq. 3) at ``R = h / cos 30°``, the scan filter
    (eqs. 4-7, :func:`scan_transfer` over ``l_az``) and the 10-min high-pass ``H_T`` of
    :func:`averaging_window_transfer` that both instruments share. ``s_TP`` is the
    variance of the radial-velocity residuals about the fitted cosine,
    ``(TP U)²`` (eq. 13), as a fraction of the cup's 10-min variance: scales below
    ``l_az`` that the probe still resolves (eq. 12, the high-pass complement of the
    scan filter).

    Parameters
    ----------
    height : float
        Measurement height above the lidar (m), > 0.
    wind_speed : float
        Mean horizontal wind speed (m s-1), > 0.
    scan_time_s : float
        Scan duration behind one wind vector (s): 1 or 3.
    z_r_coefficient : float
        ``c`` of ``Z_R = c R²`` (1/m).
    window_s : float
        Averaging window of the statistics (s).

    Returns
    -------
    ratio : float
        ``sigma_lidar / sigma_cup`` (1).
    tp_share : float
        ``(TP U)² / sigma_cup²`` (1).
    """
    if not (height > 0 and wind_speed > 0 and scan_time_s > 0):
        raise ValueError("height, wind_speed and scan_time_s must be > 0")
    k = _wavenumbers(height)
    cup = kaimal_spectrum(k, height) * averaging_window_transfer(k, wind_speed, window_s)
    probe = lorentzian_transfer(k, zephir_rayleigh_range(height, z_r_coefficient))
    scan = scan_transfer(k, azimuth_length_scale(height, wind_speed, scan_time_s))
    cup_var = _integrate_log(cup, k)
    lidar_var = _integrate_log(cup * probe * scan, k)
    tp_var = _integrate_log(kaimal_spectrum(k, height) * probe * (1.0 - scan), k)
    return float(np.sqrt(lidar_var / cup_var)), tp_var / cup_var


def std_ratio_table(
    heights: npt.ArrayLike,
    wind_speeds: npt.ArrayLike,
    scan_time_s: float,
    *,
    z_r_coefficient: float = ZEPHIR_Z_R_COEFFICIENT,
    window_s: float = 600.0,
) -> tuple[FloatArray, FloatArray]:
    """:func:`std_ratio_and_tp_share` on a grid of heights x wind speeds.

    Parameters
    ----------
    heights : array_like
        Heights (m), shape (H,).
    wind_speeds : array_like
        Wind speeds (m s-1), shape (U,).
    scan_time_s, z_r_coefficient, window_s
        As in :func:`std_ratio_and_tp_share`.

    Returns
    -------
    ratio, tp_share : ndarray
        Shape (H, U).
    """
    h = np.atleast_1d(np.asarray(heights, dtype=float))
    u = np.atleast_1d(np.asarray(wind_speeds, dtype=float))
    ratio = np.empty((h.size, u.size))
    share = np.empty((h.size, u.size))
    for i, hi in enumerate(h):
        for j, uj in enumerate(u):
            ratio[i, j], share[i, j] = std_ratio_and_tp_share(
                hi, uj, scan_time_s, z_r_coefficient=z_r_coefficient, window_s=window_s
            )
    return ratio, share
