"""Configuration sections of the products beside the wind and turbulence profile.

The Level-1 Doppler lidar product, the sonic structure-function typing, the ZephIR
records and the WindCube DBS turbulence: frozen dataclasses that
:class:`cwproc.config.Config` holds (and re-exports), validated in ``__post_init__``
like the sections of :mod:`cwproc.config`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


def require_positive(obj: Any, *names: str) -> None:
    """Raise ``ValueError`` naming the first of ``names`` not a finite number > 0."""
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")


@dataclass(frozen=True)
class DopplerLidarConfig:
    """The Level-1 stare product ``<unit>_doppler_lidar.nc`` (stage ``doppler_lidar``).

    Attenuated backscatter beta from the background-corrected SNR with the telescope
    focus function (Pentikäinen et al. (2020)), the depolarisation ratio from paired
    co/cross-polarised rays (Vakkari et al. (2021)), and a screening flag on intensity
    and velocity texture together (docs/doppler-lidar.md). Off by default: a day of
    1.3-s rays is a large file; ``cwproc retrieve --l1`` or ``--layout cloudnet`` turns
    it on.
    """

    enabled: bool = False
    #: folder of the cross-polarised .hpl files (same names as the co files, with their own
    #: Background_*.txt beside them, as Cloudnet sites upload them tagged "cross"); "" = none
    cross_folder: str = ""
    #: lidar-equation constants (Pentikäinen et al. (2020), uncalibrated Stream Line values)
    wavelength_m: float = 1.565e-6
    receiver_bandwidth_hz: float = 50e6
    pulse_energy_j: float = 1e-5
    effective_diameter_m: float = 25e-3
    quantum_efficiency: float = 1.0
    #: polariser bleed-through b of delta = beta_x / beta_co - b
    bleed_through: float = 0.0
    #: gates nearer than this (m) are noise (three pulse lengths)
    near_range_m: float = 90.0
    #: box of the screening statistics: rays x gates
    box_rays: int = 5
    box_gates: int = 3
    #: box-mean SNR above this many noise standard errors is signal
    snr_sigma: float = 5.0
    #: velocity texture (box median absolute deviation, m s-1) of a coherent signal
    texture_max_m_s: float = 1.0

    def __post_init__(self) -> None:
        require_positive(
            self,
            "wavelength_m",
            "receiver_bandwidth_hz",
            "pulse_energy_j",
            "effective_diameter_m",
            "quantum_efficiency",
            "snr_sigma",
            "texture_max_m_s",
            "box_rays",
            "box_gates",
        )
        if not (math.isfinite(self.near_range_m) and self.near_range_m >= 0):
            raise ValueError("near_range_m: must be a finite number >= 0")
        if not (math.isfinite(self.bleed_through) and 0 <= self.bleed_through < 1):
            raise ValueError("bleed_through: must be in [0, 1)")


@dataclass(frozen=True)
class SonicConfig:
    """Structure-function typing of sonic data (stage ``sonic_sf``), Gladkikh et al. (2014).

    The two rules the paper leaves unstated are explicit here (docs/sonic.md):
    precedence among the nested types (``precedence_tolerance``,
    ``curvature_tolerance``) and how r_p and r_l of type 3 are found (r_p: end of the
    parabola grown from r_min; r_l: smallest start >= r_p meeting the type-3 rules).
    """

    #: analysis window Delta t (s); 600 in Gladkikh et al. (2014)
    window_s: float = 600.0
    #: running-mean window removed before the structure functions (s); 60 in the paper
    running_mean_s: float = 60.0
    #: largest lag as a fraction of the window; 0.1 in the paper
    max_lag_fraction: float = 0.1
    #: determination-coefficient threshold k_dL; 0.99850 in the paper
    kd_threshold: float = 0.99850
    #: r_N (m): lag of the normalisation (eq. 3), smallest accepted r_max, largest r_min
    normalisation_lag_m: float = 1.0
    #: precedence (decades of r_max): the simplest type whose lg r_max is within this of
    #: the largest lg r_max wins (nested models: the parabola always reaches farther)
    precedence_tolerance: float = 0.05
    #: precedence (decades of lg D): a parabola whose curvature term changes lg D by less
    #: than this over its range, |a2| (x_max - x_min)^2 / 8, counts as a line (type 1)
    curvature_tolerance: float = 0.03
    #: fewest lags in a fit and in each part of a type-3 fit
    min_fit_points: int = 5
    #: windows with a smaller fraction of valid samples are skipped (window_flag 1)
    min_valid_fraction: float = 0.9
    #: azimuth of the +x (u) axis of the sonic's instrument frame, degrees clockwise from
    #: north (x, y, z right-handed, z up): turns the window-mean wind into the geographic
    #: wind_direction of the product; the types do not depend on it
    orientation_deg: float = 0.0

    def __post_init__(self) -> None:
        require_positive(
            self, "window_s", "running_mean_s", "max_lag_fraction", "normalisation_lag_m"
        )
        if not 0 < self.kd_threshold < 1:
            raise ValueError("kd_threshold: must be in (0, 1)")
        if not 0 < self.max_lag_fraction <= 0.5:
            raise ValueError("max_lag_fraction: must be in (0, 0.5]")
        if not self.precedence_tolerance >= 0:
            raise ValueError("precedence_tolerance: must be >= 0")
        if not self.curvature_tolerance >= 0:
            raise ValueError("curvature_tolerance: must be >= 0")
        if self.min_fit_points < 4:
            raise ValueError("min_fit_points: must be >= 4 (a parabola has 3 coefficients)")
        if not 0 < self.min_valid_fraction <= 1:
            raise ValueError("min_valid_fraction: must be in (0, 1]")


@dataclass(frozen=True)
class ZephirConfig:
    """QC of wind records, ZephIR and WindCube (``[zephir]``, also ``[wind_record]``)."""

    #: fewest 1-s scan packets in a 10-min average at one height; ZephIR 300 cycling 11
    #: heights gets at most 36-37 per 10 min (unit 317 export), and Wagner et al. (DTU),
    #: sect. 4.1 keep periods with >= 65 % of the possible samples: 0.65 x 37 -> 24
    min_packets: int = 24
    #: largest proportion of packets with rain (%) (Wagner et al. (DTU) excluded rain)
    max_rain_percent: float = 50.0

    def __post_init__(self) -> None:
        if self.min_packets < 0:
            raise ValueError("min_packets: must be >= 0")
        if not 0 <= self.max_rain_percent <= 100:
            raise ValueError("max_rain_percent: must be in [0, 100]")


@dataclass(frozen=True)
class DbsConfig:
    """Turbulence intensity from WindCube ``.rtd`` lines of sight (docs/windcube.md)."""

    #: interval of the statistics (s)
    window_s: float = 600.0
    #: lines of sight with a lower CNR (dB) are missing (the WindCube's CNRThreshold)
    min_cnr_db: float = -23.0
    #: pulsed range weighting of the volume-averaging model: Delta_p = c sigma_p / 2 and
    #: the range window Delta_R (m); defaults of cwproc's virtual WindCube (assumed)
    delta_p_m: float = 15.0
    delta_r_m: float = 20.0
    #: accumulation behind one line of sight, for the noise variance from the CNR
    #: (Pearson et al. (2009), eq. 3); assumed (WF 2.x files write NA)
    points_per_gate: float = 10.0
    pulses_per_los: float = 10000.0
    #: integral scale L_V (m) of the isotropic von Karman model of the corrections;
    #: unset: 2 x 0.7 min(h, 60 m) (the IEC 61400-1 Kaimal scale L_u / 4)
    integral_scale_m: float | None = None
    #: fewer complete beam cycles than this share (%) flags an interval
    min_cycles_percent: float = 80.0
    #: largest difference of w from the inclined and the vertical beams (m s-1) before an
    #: interval is flagged inhomogeneous (complex terrain)
    max_w_mismatch: float = 0.3

    def __post_init__(self) -> None:
        if not self.window_s > 0:
            raise ValueError("window_s: must be > 0")
        for name in ("delta_p_m", "delta_r_m", "points_per_gate", "pulses_per_los"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: must be > 0")
        if self.integral_scale_m is not None and not self.integral_scale_m > 0:
            raise ValueError("integral_scale_m: must be > 0")
        if not 0 <= self.min_cycles_percent <= 100:
            raise ValueError("min_cycles_percent: must be in [0, 100]")
