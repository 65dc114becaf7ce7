"""Attenuated backscatter and depolarisation ratio of a heterodyne pulsed Doppler lidar.

The heterodyne lidar equation (Pentikäinen et al. (2020), eqs. 1-3, after Frehlich and
Kavaya (1991)) gives the wide-band SNR of a range gate at distance ``R`` as

    SNR(R) = eta E c beta(R) A_e(R) / (2 h nu B R^2)

with ``eta`` the detector quantum efficiency, ``E`` the pulse energy, ``B`` the receiver
bandwidth, ``nu = c / lambda`` and ``A_e`` the effective receiver area of a focused
Gaussian beam (the telescope "focus function", Pentikäinen et al. (2020), eq. 3):

    A_e(R) = (pi D^2 / 4) / (1 + (pi D^2 / (4 lambda R))^2 (1 - R / f)^2)

``D`` the effective beam diameter and ``f`` the focus distance. Solving for beta gives
the attenuated backscatter that Cloudnet writes for the Halo Stream Line. The
instrument constants are the *uncalibrated* values of Pentikäinen et al. (2020) that the
ACTRIS Cloudnet processing (doppy) uses: beta is an absolute number only to within the
calibration of ``E``, ``D`` and ``eta``; ratios (depolarisation) are not affected.

Depolarisation ratio (Vakkari et al. (2021), eq. 1): ``delta = (beta_x - b beta_co) /
beta_co``, the co- and cross-polarised backscatter of the same gate from two rays
measured back to back, ``b`` the polariser bleed-through (0 for an ideal polariser).
Because both rays share the telescope and constants, ``delta = SNR_x/SNR_co - b``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cwproc.references import PENTIKAINEN_2020, VAKKARI_2021

#: Planck constant (J s) and speed of light (m s-1), CODATA 2018 exact values
PLANCK_J_S = 6.62607015e-34
SPEED_OF_LIGHT_M_S = 299792458.0
#: the Stream Line's ``Focus range`` for a collimated (unfocused) beam: 2**16 - 1 m
UNFOCUSED_FOCUS_M = 65535.0


@dataclass(frozen=True)
class LidarConstants:
    """Instrument constants of the lidar equation (Pentikäinen et al. (2020), Table 1).

    The defaults are the Halo Stream Line's: wavelength 1.565 um, 50 MHz receiver
    bandwidth (the digitiser rate), the uncalibrated pulse energy 10 uJ and effective
    beam diameter 25 mm, quantum efficiency 1 (as the ACTRIS Cloudnet processing uses
    them).
    """

    wavelength_m: float = 1.565e-6
    receiver_bandwidth_hz: float = 50e6
    pulse_energy_j: float = 1e-5
    effective_diameter_m: float = 25e-3
    quantum_efficiency: float = 1.0

    def __post_init__(self) -> None:
        for name in (
            "wavelength_m",
            "receiver_bandwidth_hz",
            "pulse_energy_j",
            "effective_diameter_m",
            "quantum_efficiency",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name}: must be a finite number > 0, not {value!r}")


def effective_receiver_area(
    range_m: np.ndarray, focus_m: float, constants: LidarConstants = LidarConstants()
) -> np.ndarray:
    """Effective receiver area A_e(R) of a focused Gaussian beam (m2).

    Pentikäinen et al. (2020), eq. 3. ``focus_m`` of the Stream Line's collimated
    setting (65535, :data:`UNFOCUSED_FOCUS_M`) or larger, or not finite, means an
    infinite focus: ``(1 - R/f)`` is then 1.

    Parameters
    ----------
    range_m : numpy.ndarray
        Distance from the lidar (m), > 0.
    focus_m : float
        Focus distance of the telescope (m), the ``.hpl`` header's ``Focus range``.
    constants : LidarConstants
        Wavelength and effective beam diameter.
    """
    r = np.asarray(range_m, dtype=float)
    d2 = constants.effective_diameter_m**2
    defocus = (
        np.ones_like(r)
        if not np.isfinite(focus_m) or focus_m >= UNFOCUSED_FOCUS_M
        else 1.0 - r / float(focus_m)
    )
    fresnel = np.pi * d2 / (4.0 * constants.wavelength_m * r)
    return np.pi * d2 / 4.0 / (1.0 + fresnel**2 * defocus**2)


def attenuated_backscatter(
    snr: np.ndarray,
    range_m: np.ndarray,
    focus_m: float,
    constants: LidarConstants = LidarConstants(),
) -> np.ndarray:
    """Attenuated backscatter beta (m-1 sr-1) from the wide-band SNR of each gate.

    ``beta = 2 h nu B R^2 SNR / (eta c E A_e(R))`` (Pentikäinen et al. (2020), eqs. 1-3
    solved for beta). ``snr`` is (..., range); ``range_m`` is broadcast along its last
    axis. Negative SNR (noise) gives negative beta, as the instrument writes it.
    """
    r = np.asarray(range_m, dtype=float)
    nu = SPEED_OF_LIGHT_M_S / constants.wavelength_m
    area = effective_receiver_area(r, focus_m, constants)
    scale = (
        2.0
        * PLANCK_J_S
        * nu
        * constants.receiver_bandwidth_hz
        * r**2
        / (constants.quantum_efficiency * SPEED_OF_LIGHT_M_S * constants.pulse_energy_j * area)
    )
    return np.asarray(snr, dtype=float) * scale


def depolarisation_ratio(
    snr_co: np.ndarray,
    snr_cross: np.ndarray,
    snr_co_std: np.ndarray,
    snr_cross_std: np.ndarray,
    bleed_through: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Linear depolarisation ratio and its standard error from paired co/cross SNR.

    Vakkari et al. (2021), eq. 1: ``delta = SNR_x / SNR_co - b`` (the lidar constants
    and the focus function cancel). The error propagates the independent noise of the
    two SNRs to first order: ``SE(delta) = (SNR_x/SNR_co) sqrt((s_x/SNR_x)^2 +
    (s_co/SNR_co)^2)`` -- written as ``sqrt(s_x^2 + (SNR_x/SNR_co)^2 s_co^2) / SNR_co``
    so that it stays finite when ``SNR_x`` is 0. Gates with ``SNR_co <= 0`` give NaN.

    Parameters
    ----------
    snr_co, snr_cross : numpy.ndarray
        Background-corrected SNR of the paired co- and cross-polarised gates.
    snr_co_std, snr_cross_std : numpy.ndarray
        Their noise standard deviations (broadcastable).
    bleed_through : float
        Polariser bleed-through ``b`` (fraction of the co-polarised signal that
        reaches the cross channel).
    """
    co = np.asarray(snr_co, dtype=float)
    x = np.asarray(snr_cross, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(co > 0, x / co, np.nan)
        se = np.sqrt(np.asarray(snr_cross_std) ** 2 + ratio**2 * np.asarray(snr_co_std) ** 2) / co
    return ratio - bleed_through, np.where(co > 0, se, np.nan)


def references() -> str:
    """The papers of this module, for a product's attributes."""
    return f"{PENTIKAINEN_2020}; {VAKKARI_2021}"
