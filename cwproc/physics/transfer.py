"""Probe-volume transfer functions of Doppler lidars (wavenumbers in cycles per metre).

A lidar measures the radial velocity averaged along the beam with a range weighting
``Q(s)`` (``s`` along the beam from the probe centre) and, while the beam moves during
the accumulation of one ray, averaged across the scan over the transverse sampling
``dy``. In the spectral domain these averages multiply the 2-D spectrum of the radial
velocity by the squared moduli of the Fourier transforms of the weightings: the
longitudinal transfer function ``H_par(kappa1)`` and the transverse one
``H_perp(kappa2)`` (Smalikho (2020), eqs. 16-20).

Conventions: ``kappa`` is in cycles per metre, the Fourier transform is
``int Q(s) exp(-2 pi i kappa s) ds``, so a lag ``r`` enters as ``cos(2 pi r kappa)``.

- Pulsed lidar (Smalikho (2020), eq. 19): Gaussian pulse ``exp(-s^2/dp^2)`` convolved
  with the range gate of length ``dR``; its transform is ``exp(-(pi dp kappa)^2)
  sinc(pi dR kappa)``. The extracted eq. 19 prints ``exp(-(dp kappa)^2)``, without the
  ``pi``; with ``kappa`` in cycles per metre only the form with ``pi`` is the transform of
  the physical weighting, and only it reproduces the three figure claims of the paper
  on epsilon_1/epsilon_2 versus mu (Smalikho (2020), eqs. 21-23). ``gaussian="printed"`` keeps the
  printed form as an option.
- Continuous-wave lidar (Banakh et al. (1999) Q_s; Wagner et al. (DTU), eq. 2): the
  Lorentzian ``Q(s) = (w / pi) / (w^2 + s^2)``; its transform is ``exp(-2 pi w |kappa|)``,
  so ``H_par = exp(-4 pi w |kappa|)``. With the wavelength and the beam radius known,
  Banakh et al. (1999) Q_s (after eq. 3, with ``k0 a0^2`` squared so that the
  dimensions agree) gives the half width ``w = z_R / (1 + (R/z_d)^2)``, centred at
  ``R / (1 + (R/z_d)^2)``, with ``z_d = k0 a0^2 = 2 pi a0^2 / lambda`` and
  ``z_R = lambda R^2 / (2 pi a0^2)``; ZephIR's empirical ``w = Z_R = 0.0013 R^2``
  (Wagner et al. (DTU)) has no such correction.
- Transverse (Smalikho (2020), eq. 20): ``H_perp = sinc^2(pi dy kappa)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy import special

from cwproc.physics.constants import (
    STREAMLINE_DELTA_P_M,
    STREAMLINE_DELTA_R_M,
    ZEPHIR_Z_R_COEFFICIENT,
)
from cwproc.physics.cw_probe import focal_parameter, lorentzian_parameters

#: speed of light (m s-1)
SPEED_OF_LIGHT = 299_792_458.0


def _sinc(x: np.ndarray) -> np.ndarray:
    """``sin(x)/x`` with the value 1 at 0 (numpy's ``sinc`` is ``sin(pi x)/(pi x)``)."""
    return np.sinc(np.asarray(x, dtype=float) / np.pi)


def transverse(kappa: ArrayLike, dy: float) -> np.ndarray:
    """Transverse transfer function ``H_perp = sinc^2(pi dy kappa)``.

    Smalikho (2020), eq. 20: averaging over the transverse sampling ``dy`` while the beam
    moves during the accumulation of one ray.

    Parameters
    ----------
    kappa : array_like
        Transverse wavenumber (cycles m-1).
    dy : float
        Transverse size of the probe volume, ``dy = dtheta h / tan(phi)`` (m); 0 means no
        transverse averaging (``H_perp = 1``).

    Returns
    -------
    numpy.ndarray
        ``H_perp`` (1), same shape as ``kappa``.
    """
    return _sinc(np.pi * dy * np.asarray(kappa, dtype=float)) ** 2


@dataclass(frozen=True)
class PulsedProbe:
    """Range weighting of a pulsed coherent Doppler lidar (Smalikho (2020), eq. 19).

    Parameters
    ----------
    delta_p_m : float
        ``dp = c sigma_p / 2`` (m), the 1/e half width of the Gaussian pulse in range;
        Stream Line 15.3 m.
    delta_r_m : float
        ``dR = c T_w / 2`` (m), the range-gate length; Stream Line 18 m.
    gaussian : {"physical", "printed"}
        ``"physical"``: ``exp(-(pi dp kappa)^2)``, the transform of the Gaussian weight
        (default); ``"printed"``: ``exp(-(dp kappa)^2)`` exactly as the extracted eq. 19.
    """

    delta_p_m: float = STREAMLINE_DELTA_P_M
    delta_r_m: float = STREAMLINE_DELTA_R_M
    gaussian: Literal["physical", "printed"] = "physical"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.delta_p_m) and self.delta_p_m >= 0):
            raise ValueError(f"delta_p_m must be finite and >= 0, got {self.delta_p_m!r}")
        if not (math.isfinite(self.delta_r_m) and self.delta_r_m >= 0):
            raise ValueError(f"delta_r_m must be finite and >= 0, got {self.delta_r_m!r}")
        if self.gaussian not in ("physical", "printed"):
            raise ValueError(f"gaussian must be 'physical' or 'printed', got {self.gaussian!r}")

    @property
    def gaussian_width_m(self) -> float:
        """Width ``w`` (m) in ``exp(-(w kappa)^2)``: ``pi dp`` (physical) or ``dp`` (printed)."""
        return math.pi * self.delta_p_m if self.gaussian == "physical" else self.delta_p_m

    def longitudinal(self, kappa: ArrayLike, range_m: ArrayLike | None = None) -> np.ndarray:
        """Longitudinal transfer function ``H_par(kappa)`` (1), Smalikho (2020), eq. 19.

        ``[exp(-(pi dp kappa)^2) sinc(pi dR kappa)]^2`` (``"physical"``) or
        ``[exp(-(dp kappa)^2) sinc(pi dR kappa)]^2`` (``"printed"``).

        Parameters
        ----------
        kappa : array_like
            Wavenumber along the beam (cycles m-1).
        range_m : array_like, optional
            Ignored (a pulsed probe does not depend on range); accepted so that pulsed
            and cw probes share one signature.
        """
        k = np.asarray(kappa, dtype=float)
        return (
            np.exp(-((self.gaussian_width_m * k) ** 2)) * _sinc(np.pi * self.delta_r_m * k)
        ) ** 2

    def centre_range(self, range_m: ArrayLike) -> np.ndarray:
        """Distance (m) of the probe centre from the lidar: the gate centre ``range_m``."""
        return np.asarray(range_m, dtype=float)

    def transverse_size(self, dy: ArrayLike) -> np.ndarray:
        """Transverse size (m) of the probe in ``H_perp`` (Smalikho (2020), eq. 20): ``dy``.

        A pulsed lidar accumulates each ray while the beam sweeps one azimuth step.
        """
        return np.asarray(dy, dtype=float)

    def length_scale_m(self, range_m: ArrayLike | None = None) -> np.ndarray:
        """A length (m) beyond whose inverse ``H_par`` is negligible (for quadrature grids)."""
        return np.asarray(max(self.gaussian_width_m, self.delta_r_m), dtype=float)

    def key(self) -> tuple:
        """Parameters that fix the transfer function (for cache keys)."""
        return ("pulsed", float(self.delta_p_m), float(self.delta_r_m), self.gaussian)


@dataclass(frozen=True)
class CWProbe:
    """Lorentzian range weighting of a focused continuous-wave lidar.

    Banakh et al. (1999), Q_s after eq. 3 (with ``k0 a0^2`` squared so that the
    dimensions agree); Wagner et al. (DTU), eq. 2.

    Parameters
    ----------
    z_r_coefficient : float
        ``c`` in ``Z_R = c R^2`` (m-1); ZephIR 0.0013 (Wagner et al. (DTU)).
    wavelength_m : float, optional
        Laser wavelength ``lambda`` (m); with ``beam_radius_m`` gives
        ``Z_R = lambda R^2 / (2 pi a0^2)``.
    beam_radius_m : float, optional
        Beam radius ``a0`` at the telescope (m).
    transverse_averaging : bool
        ``False`` (default): each Doppler spectrum is the probe-averaged velocity at one
        azimuth ``theta_m``, the model of Banakh et al. (1999), eq. 15 (and of the
        simulator :mod:`cwproc.sim.cw`), so ``H_perp = 1``; ``True``: the spectrum
        accumulates while the beam sweeps one azimuth step, ``H_perp = sinc^2(pi dy
        kappa)`` (Smalikho (2020), eq. 20).
    """

    z_r_coefficient: float = ZEPHIR_Z_R_COEFFICIENT
    wavelength_m: float | None = None
    beam_radius_m: float | None = None
    transverse_averaging: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.z_r_coefficient) and self.z_r_coefficient > 0):
            raise ValueError(f"z_r_coefficient must be > 0, got {self.z_r_coefficient!r}")
        if self.beam_radius_m is not None:
            if self.wavelength_m is None:
                raise ValueError("beam_radius_m needs wavelength_m (Z_R = lambda R^2/(2 pi a0^2))")
            if not (self.beam_radius_m > 0 and self.wavelength_m > 0):
                raise ValueError("beam_radius_m and wavelength_m must be > 0")

    @property
    def coefficient(self) -> float:
        """``c`` (m-1) in ``Z_R = c R^2``: ``lambda/(2 pi a0^2)`` if ``a0`` is given."""
        z_d = self.focal_parameter_m
        return self.z_r_coefficient if z_d is None else 1.0 / z_d

    @property
    def focal_parameter_m(self) -> float | None:
        """``z_d = k0 a0^2 = 2 pi a0^2 / lambda`` (m) when ``a0`` is given, else None.

        Banakh et al. (1999), after eq. 3.
        """
        if self.beam_radius_m is not None and self.wavelength_m is not None:
            return focal_parameter(self.wavelength_m, self.beam_radius_m)
        return None

    def rayleigh_half_width(self, range_m: ArrayLike) -> np.ndarray:
        """Half width ``w`` (m) of the Lorentzian weighting at focus distance ``range_m`` (m).

        With the beam radius known, Banakh et al. (1999), Q_s (``k0 a0^2`` squared):
        ``w = z_R / (1 + (R/z_d)^2)``, ``z_R = lambda R^2 / (2 pi a0^2)``,
        ``z_d = 2 pi a0^2 / lambda``; else ``w = Z_R = c R^2`` (Wagner et al. (DTU):
        ``c = 0.0013`` for ZephIR).
        """
        r = np.asarray(range_m, dtype=float)
        if self.focal_parameter_m is None:
            return self.coefficient * r**2
        return lorentzian_parameters(r, self.wavelength_m, self.beam_radius_m)[1]

    def focus_centre(self, range_m: ArrayLike) -> np.ndarray:
        """Centre (m from the lidar) of the Lorentzian weighting focused at ``range_m`` (m).

        ``R / (1 + (R/z_d)^2)`` (Banakh et al. (1999), Q_s with ``k0 a0^2`` squared) when
        the beam radius is known, else ``R``.
        """
        r = np.asarray(range_m, dtype=float)
        if self.focal_parameter_m is None:
            return r
        return lorentzian_parameters(r, self.wavelength_m, self.beam_radius_m)[0]

    def weighting(self, s: ArrayLike, range_m: float) -> np.ndarray:
        """Lorentzian range weighting ``Q(s) = (Z_R/pi)/(Z_R^2 + s^2)`` (m-1), unit area.

        Wagner et al. (DTU), eq. 2; ``s`` (m) is the distance from the focus along the beam.
        """
        z = self.rayleigh_half_width(range_m)
        return (z / np.pi) / (z**2 + np.asarray(s, dtype=float) ** 2)

    def longitudinal(self, kappa: ArrayLike, range_m: ArrayLike) -> np.ndarray:
        """Longitudinal transfer function ``H_par`` (1).

        ZephIR form (no beam radius): ``exp(-4 pi Z_R |kappa|)``, the squared modulus of
        the Fourier transform of the Lorentzian weighting (Wagner et al. (DTU), eq. 3).
        With ``lambda`` and ``a0``: the squared modulus of the transform of the Lorentzian
        of Banakh et al. (1999), Q_s, cut at the lidar and renormalised
        (:func:`cut_lorentzian_transform`; up to 9 % of Q_s lies behind the lidar at
        R = 1000 m for the lidar of Banakh et al. (1999)).
        ``kappa`` in cycles m-1, ``range_m`` the focus distance (m); both broadcast.
        """
        if range_m is None:
            raise ValueError("a cw probe needs the focus distance range_m")
        z = self.rayleigh_half_width(range_m)
        if self.focal_parameter_m is None:
            return np.exp(-4.0 * np.pi * z * np.abs(np.asarray(kappa, dtype=float)))
        return np.abs(cut_lorentzian_transform(kappa, z, self.focus_centre(range_m))) ** 2

    def centre_range(self, range_m: ArrayLike) -> np.ndarray:
        """Distance (m) of the probe centre from the lidar (:meth:`focus_centre`).

        The scan circle the probe samples has the radius ``centre_range cos(phi)``.
        """
        return self.focus_centre(range_m)

    def transverse_size(self, dy: ArrayLike) -> np.ndarray:
        """Transverse size (m) of the probe in ``H_perp``: ``dy`` with sweep averaging, else 0.

        See ``transverse_averaging`` (Banakh et al. (1999), eq. 15; Smalikho (2020),
        eq. 20).
        """
        d = np.asarray(dy, dtype=float)
        return d if self.transverse_averaging else np.zeros_like(d)

    def length_scale_m(self, range_m: ArrayLike) -> np.ndarray:
        """A length (m) beyond whose inverse ``H_par`` is negligible (for quadrature grids)."""
        return 4.0 * np.pi * self.rayleigh_half_width(range_m)

    def key(self) -> tuple:
        """Parameters that fix the transfer function (for cache keys)."""
        z_d = self.focal_parameter_m
        return (
            "cw",
            float(self.coefficient),
            None if z_d is None else float(z_d),
            bool(self.transverse_averaging),
        )


Probe = PulsedProbe | CWProbe


def _exp_e1(z: np.ndarray) -> np.ndarray:
    """``exp(z) E1(z)`` for complex ``z`` off the negative real axis (asymptotic for |z| > 40)."""
    z = np.asarray(z, dtype=complex)
    big = np.abs(z) > 40.0
    zs = np.where(big, 1.0, z)
    zb = np.where(big, z, 1.0)
    direct = np.exp(zs) * special.exp1(zs)
    series = (1.0 - 1.0 / zb + 2.0 / zb**2 - 6.0 / zb**3 + 24.0 / zb**4) / zb
    return np.where(big, series, direct)


def cut_lorentzian_transform(
    kappa: ArrayLike, half_width_m: ArrayLike, centre_m: ArrayLike
) -> np.ndarray:
    """Fourier transform of a Lorentzian cut at the lidar and renormalised (1, complex).

    ``Q(s) = (w/pi)/(w^2 + s^2) / K`` for ``s >= -a`` (``s`` from the centre, ``a`` the
    centre's distance from the lidar), ``K = 1/2 + atan(a/w)/pi``: Banakh et al. (1999),
    Q_s, with the part behind the lidar cut.
    ``F = [exp(-w k) - T(k)] / K`` with ``k = 2 pi |kappa|`` and the cut tail
    ``T = int_a^inf (w/pi) exp(i k u)/(w^2 + u^2) du
    = exp(i k a) [g(-k w - i k a) - g(k w - i k a)] / (2 pi i)``, ``g(z) = exp(z) E1(z)``
    (partial fractions of the Lorentzian; ``E1`` the exponential integral). The sign of
    the imaginary part follows ``kappa``'s (``F(-kappa)`` is the conjugate).

    Parameters
    ----------
    kappa : array_like
        Wavenumber (cycles m-1).
    half_width_m : array_like
        ``w`` (m), > 0.
    centre_m : array_like
        ``a`` (m), >= 0. All three broadcast.
    """
    kappa = np.asarray(kappa, dtype=float)
    w = np.asarray(half_width_m, dtype=float)
    a = np.asarray(centre_m, dtype=float)
    k = 2.0 * np.pi * np.abs(kappa)
    zero = k == 0
    ks = np.where(zero, 1.0, k)
    tail = (
        np.exp(1j * ks * a)
        * (_exp_e1(-ks * w - 1j * ks * a) - _exp_e1(ks * w - 1j * ks * a))
        / (2j * np.pi)
    )
    norm = 0.5 + np.arctan(a / w) / np.pi
    f = (np.exp(-ks * w) - tail) / norm
    f = np.where(kappa < 0, np.conj(f), f)
    return np.where(zero, 1.0 + 0j, f)


def pulse_parameters(pulse_fwhm_s: float, window_s: float) -> tuple[float, float]:
    """Probe lengths of a pulsed lidar from its pulse and range-gate durations.

    Smalikho (2020), eq. 19: ``dp = c sigma_p / 2`` with ``sigma_p = tau_p / (2 sqrt(ln 2))``
    and ``dR = c T_w / 2``.

    Parameters
    ----------
    pulse_fwhm_s : float
        Pulse duration ``tau_p`` (s, full width at half maximum of the power).
    window_s : float
        Range-gate (time window) duration ``T_w`` (s).

    Returns
    -------
    (float, float)
        ``(delta_p_m, delta_r_m)`` in metres.
    """
    if not (pulse_fwhm_s >= 0 and window_s >= 0):
        raise ValueError("pulse and window durations must be >= 0")
    sigma_p = pulse_fwhm_s / (2.0 * math.sqrt(math.log(2.0)))
    return SPEED_OF_LIGHT * sigma_p / 2.0, SPEED_OF_LIGHT * window_s / 2.0
