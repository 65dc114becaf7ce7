"""One declaration per variable that cwproc writes: CF-1.10 attributes of every product.

Stages and readers never write ``units``/``standard_name``/``long_name`` strings
themselves: they name variables as listed here and :func:`apply_metadata` (called by
the NetCDF writer) attaches the attributes. A test checks that every variable of
every product is declared here. Stage-specific attributes that describe *what was
done* (method, parameters, references) are set by the stages in ``attrs`` and are
kept.

To add a variable: add one :class:`VarMeta` entry to ``VARIABLES`` (keep the table
grouped by product).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import xarray as xr

from cwproc.references import (
    BANAKH_1999,
    GLADKIKH_2014,
    OCONNOR_2010,
    SMALIKHO_2020,
    WAGNER_DTU,
)


@dataclass(frozen=True)
class VarMeta:
    """CF attributes of one variable."""

    long_name: str
    units: str | None
    standard_name: str | None = None
    comment: str | None = None
    references: str | None = None
    #: flag variables: values and their meanings (CF flag_values / flag_meanings)
    flag_values: tuple[int, ...] | None = None
    #: bit flags: the masks (CF flag_masks) whose meanings ``flag_meanings`` lists
    flag_masks: tuple[int, ...] | None = None
    flag_meanings: str | None = None
    #: CF "positive" attribute for vertical coordinates
    positive: str | None = None
    axis: str | None = None
    #: ACDD coverage_content_type: physicalMeasurement, qualityInformation,
    #: auxiliaryInformation, coordinate, modelResult, referenceInformation
    coverage_content_type: str = "physicalMeasurement"

    def attrs(self) -> dict[str, object]:
        """The attributes as a dict, without the ``None`` entries."""
        out: dict[str, object] = {"long_name": self.long_name}
        if self.units is not None:
            out["units"] = self.units
        keys = (
            "standard_name",
            "comment",
            "references",
            "flag_meanings",
            "positive",
            "axis",
            "coverage_content_type",
        )
        for key in keys:
            value = getattr(self, key)
            if value is not None:
                out[key] = value
        if self.flag_values is not None:
            out["flag_values"] = list(self.flag_values)
        if self.flag_masks is not None:
            out["flag_masks"] = list(self.flag_masks)
        return out


VARIABLES: dict[str, VarMeta] = {
    # ---------------------------------------------------------------- coordinates
    "time": VarMeta("time (UTC)", None, "time", axis="T", coverage_content_type="coordinate"),
    "height": VarMeta(
        "height above the instrument",
        "m",
        "height",
        positive="up",
        axis="Z",
        coverage_content_type="coordinate",
    ),
    "range": VarMeta("distance from the lidar to the centre of the range gate", "m"),
    "latitude": VarMeta(
        "latitude of the instrument",
        "degrees_north",
        "latitude",
        axis="Y",
        coverage_content_type="coordinate",
    ),
    "longitude": VarMeta(
        "longitude of the instrument",
        "degrees_east",
        "longitude",
        axis="X",
        coverage_content_type="coordinate",
    ),
    "altitude": VarMeta(
        "altitude of the instrument above mean sea level",
        "m",
        "altitude",
        positive="up",
        coverage_content_type="coordinate",
    ),
    "azimuth": VarMeta(
        "azimuth of the beam, clockwise from north", "degree", "sensor_azimuth_angle"
    ),
    "elevation": VarMeta("elevation of the beam above the horizon", "degree"),
    "scan": VarMeta("index of the 360 degree rotation the ray belongs to", "1"),
    "lag": VarMeta("azimuth lag number l of the structure function", "1"),
    "ray": VarMeta("ray index", "1"),
    # ---------------------------------------------------------------- scan dataset
    "radial_velocity": VarMeta(
        "radial (line-of-sight) velocity, positive away from the lidar",
        "m s-1",
        "radial_velocity_of_scatterers_away_from_instrument",
    ),
    "snr": VarMeta("signal-to-noise ratio (Halo intensity minus 1)", "1"),
    "beta": VarMeta("attenuated backscatter coefficient", "m-1 sr-1"),
    "spectral_width": VarMeta("Doppler spectral width", "m s-1"),
    "pitch": VarMeta("instrument pitch from the internal inclinometer", "degree", "platform_pitch"),
    "roll": VarMeta("instrument roll from the internal inclinometer", "degree", "platform_roll"),
    "qc_flag_radial": VarMeta(
        "radial velocity screening flag (bits combine; 0 = good)",
        "1",
        comment="0 good; bit 1 SNR below threshold; bit 2 robust outlier; bit 4 not finite",
        flag_masks=(1, 2, 4),
        flag_meanings="low_snr outlier not_finite",
    ),
    # ---------------------------------------------------------------- wind product
    "u": VarMeta("eastward wind", "m s-1", "eastward_wind"),
    "v": VarMeta("northward wind", "m s-1", "northward_wind"),
    "w": VarMeta("upward air velocity", "m s-1", "upward_air_velocity"),
    "wind_speed": VarMeta("horizontal wind speed", "m s-1", "wind_speed"),
    "wind_direction": VarMeta(
        "wind direction (from which the wind blows, clockwise from north)",
        "degree",
        "wind_from_direction",
    ),
    "u_error": VarMeta(
        "standard error of the eastward wind", "m s-1", "eastward_wind standard_error"
    ),
    "v_error": VarMeta(
        "standard error of the northward wind", "m s-1", "northward_wind standard_error"
    ),
    "w_error": VarMeta(
        "standard error of the upward air velocity",
        "m s-1",
        "upward_air_velocity standard_error",
    ),
    "wind_speed_error": VarMeta(
        "standard error of the horizontal wind speed", "m s-1", "wind_speed standard_error"
    ),
    "wind_direction_error": VarMeta(
        "standard error of the wind direction", "degree", "wind_from_direction standard_error"
    ),
    "residual_std": VarMeta(
        "standard deviation of the radial-velocity residuals about the VAD fit", "m s-1"
    ),
    "n_rays": VarMeta("number of rays used in the VAD fit", "1"),
    "max_azimuth_gap": VarMeta("largest azimuth gap between rays used in the fit", "degree"),
    "qc_flag": VarMeta(
        "wind quality flag (bits combine; 0 = good)",
        "1",
        flag_masks=(1, 2, 4, 8),
        flag_meanings="too_few_samples azimuth_gap_too_large bad_fit_or_missing rain",
        comment=(
            "0 good; bit 1 too few rays (VAD) or packets (wind records); bit 2 azimuth gap "
            "too large (VAD); bit 4 bad fit (VAD) or missing value (wind records); bit 8 "
            "too many packets with rain (wind records)"
        ),
    ),
    # ---------------------------------------------------------------- turbulence product
    "structure_function": VarMeta(
        "azimuth structure function of the radial velocity D_L(l dtheta)",
        "m2 s-2",
        references=SMALIKHO_2020 + ", eqs. 1-2",
    ),
    "n_pairs": VarMeta("number of ray pairs in the structure function", "1"),
    "structure_function_model": VarMeta(
        "fitted model of the azimuth structure function eps^(2/3) A_2 + 2 sigma_e^2",
        "m2 s-2",
        references=SMALIKHO_2020 + ", eq. 4",
    ),
    "epsilon": VarMeta(
        "turbulent kinetic energy dissipation rate (method 2: volume averaging and wind "
        "transport accounted for)",
        "m2 s-3",
        references=SMALIKHO_2020 + ", eqs. 4-5, 15-20 (least squares of eq. 4 over all lags)",
    ),
    "epsilon_method1": VarMeta(
        "turbulent kinetic energy dissipation rate (method 1: no wind transport)",
        "m2 s-3",
        references=SMALIKHO_2020 + ", eqs. 4-5 with A_1 = A_perp (least squares over all lags)",
    ),
    "epsilon_ratio": VarMeta(
        "ratio of the method-1 to the method-2 dissipation rate estimates",
        "1",
        references=SMALIKHO_2020 + ", eq. 21",
    ),
    "mu": VarMeta("ratio of the mean wind speed to the linear scanning speed, U/V_s", "1"),
    "scan_speed": VarMeta("linear scanning speed V_s = 2 pi h/(T_scan tan phi)", "m s-1"),
    "transverse_resolution": VarMeta(
        "transverse sampling interval dy = dtheta R'", "m", references=SMALIKHO_2020
    ),
    "noise_std": VarMeta(
        "instrumental error of the radial velocity sigma_e",
        "m s-1",
        "radial_velocity_of_scatterers_away_from_instrument standard_error",
        references=SMALIKHO_2020,
    ),
    "velocity_variance": VarMeta(
        "variance of the radial velocity, corrected for noise and volume averaging",
        "m2 s-2",
        references=BANAKH_1999,
    ),
    "integral_scale": VarMeta(
        "integral scale of turbulence L_V", "m", references=BANAKH_1999 + ", eq. 19"
    ),
    "n_scans": VarMeta("number of scans in the block", "1"),
    "turbulence_flag": VarMeta(
        "dissipation-rate quality flag (bits combine)",
        "1",
        flag_masks=(1, 2, 4, 8, 16, 32),
        flag_meanings=(
            "too_few_pairs lag_beyond_inertial_range mu_beyond_method1 fit_failed "
            "partial_block noise_predicted"
        ),
        comment=(
            "0 good; bit 1 too few pairs; bit 2 lag beyond the inertial range; "
            "bit 4 mu beyond method 1 validity (epsilon_method1 is kept); bit 8 fit failed; "
            "bit 16 partial block (fewer than half the requested scans per block); bit 32 "
            "the fitted noise intercept is not significant (below twice its standard "
            "error) or negative: noise_std is the prediction from the SNR, used in the fit"
        ),
    ),
    # ------------------------------------------- turbulence product: issue-12 additions
    "edr": VarMeta(
        "eddy dissipation rate, the cube root of the turbulent kinetic energy dissipation rate",
        "m2/3 s-1",
        comment=(
            "EDR = epsilon^(1/3), the turbulence measure of aviation (ICAO) and NWP; units "
            "m^(2/3) s^-1, written as 'm2/3 s-1' as is customary: UDUNITS has no rational "
            "exponents and parses that string as m2 s-1 / 3, so do not convert it"
        ),
        references=SMALIKHO_2020 + ", eq. 5",
    ),
    "noise_std_predicted": VarMeta(
        "instrumental error of the radial velocity sigma_e predicted from the "
        "signal-to-noise ratio and the instrument settings",
        "m s-1",
        "radial_velocity_of_scatterers_away_from_instrument standard_error",
        comment=(
            "Pearson et al. (2009), eq. 3: points per gate, pulses per ray, velocity "
            "bandwidth 1024 x the velocity resolution, signal spectral width 1.5 m s-1, "
            "block-median SNR"
        ),
        references=(
            "Pearson G., Davies F., Collier C. (2009), J. Atmos. Oceanic Technol. 26, "
            "240-250; Rye B.J., Hardesty R.M. (1993), IEEE Trans. Geosci. Remote Sens. 31, "
            "16-27"
        ),
    ),
    "epsilon_standard_error": VarMeta(
        "standard error of the turbulent kinetic energy dissipation rate",
        "m2 s-3",
        comment=(
            "delta method through the whole fit (eps and L_V together) with the covariance "
            "of D_L(1..L) and the variance of V'_L over the block's scans (scans as "
            "independent samples)"
        ),
        coverage_content_type="qualityInformation",
    ),
    "velocity_variance_standard_error": VarMeta(
        "standard error of the radial-velocity variance sigma_V^2",
        "m2 s-2",
        comment="delta method through the whole fit, as epsilon_standard_error",
        coverage_content_type="qualityInformation",
    ),
    "integral_scale_standard_error": VarMeta(
        "standard error of the integral scale L_V",
        "m",
        comment="delta method through the whole fit, as epsilon_standard_error",
        coverage_content_type="qualityInformation",
    ),
    "structure_function_se": VarMeta(
        "standard error of the azimuth structure function from the scatter over scans",
        "m2 s-2",
        coverage_content_type="qualityInformation",
    ),
    "structure_function_difference_se": VarMeta(
        "standard error of D_L(l) - D_L(1) from the scatter over scans",
        "m2 s-2",
        coverage_content_type="qualityInformation",
    ),
    "radial_velocity_variance_se": VarMeta(
        "standard error of the variance of V'_L from the scatter over scans",
        "m2 s-2",
        coverage_content_type="qualityInformation",
    ),
    "statistics_covariance": VarMeta(
        "covariance of the block means of (D_L(1), ..., D_L(L), variance of V'_L) from "
        "the scatter over scans",
        "m4 s-4",
        coverage_content_type="qualityInformation",
    ),
    "wind_to_direction": VarMeta(
        "direction the block-mean wind blows towards", "degree", "wind_to_direction"
    ),
    "pair_azimuth_weights": VarMeta(
        "share of the lag-1 ray pairs at each azimuth node of the wind's angle from the "
        "scan direction (sectors and gaps)",
        "1",
        coverage_content_type="auxiliaryInformation",
    ),
    "azimuth_node": VarMeta(
        "angle of the mean wind's direction of motion from the scan's direction of motion",
        "degree",
    ),
    "snr_median": VarMeta(
        "block-median signal-to-noise ratio of the valid rays",
        "1",
        coverage_content_type="auxiliaryInformation",
    ),
    # ---------------------------------------------------------------- stare product
    "ray_time": VarMeta("time of the ray (UTC)", None, "time", coverage_content_type="coordinate"),
    "w_ray": VarMeta(
        "upward air velocity of each vertical ray (radial velocity screened for SNR and "
        "outliers within each variance window)",
        "m s-1",
        "upward_air_velocity",
    ),
    "w_mean": VarMeta("mean upward air velocity over the window", "m s-1", "upward_air_velocity"),
    "w_variance": VarMeta(
        "mean variance of the upward air velocity over the variance windows T of the "
        "window (noise not removed)",
        "m2 s-2",
    ),
    "w_variance_corrected": VarMeta(
        "variance of the upward air velocity of the window, instrumental noise removed",
        "m2 s-2",
        references=OCONNOR_2010,
    ),
    "w_skewness": VarMeta("skewness of the upward air velocity over the window", "1"),
    "w_noise_variance": VarMeta(
        "mean instrumental noise variance sigma_e^2 of the rays, predicted from the SNR",
        "m2 s-2",
        comment="Pearson et al. (2009), eq. 3 (cwproc.physics.noise)",
        coverage_content_type="qualityInformation",
    ),
    "w_n_samples": VarMeta(
        "number of valid rays of upward air velocity in the window",
        "1",
        "number_of_observations",  # the modifier form is deprecated since CF-1.10
        coverage_content_type="auxiliaryInformation",
    ),
    "stare_wind_speed": VarMeta(
        "horizontal wind speed U from the VADs of the day, at the window and height",
        "m s-1",
        "wind_speed",
        comment=(
            "linear in time and height between good VAD values, the nearest beyond; the "
            "length scales of O'Connor et al. (2010) are L_1 = U variance_window_s and "
            "L_N = U ray_duration_s (global attributes)"
        ),
    ),
    "epsilon_stare": VarMeta(
        "turbulent kinetic energy dissipation rate from the variance of w of a vertical stare",
        "m2 s-3",
        comment=(
            "eps = ((sigma_w^2 - sigma_e^2)/G)^(3/2), transverse constant a_T = 0.664 "
            "(C_K = 2); O'Connor et al. (2010) and doppy use a = 0.55 and sharp band "
            "limits, see docs/stare.md. Valid only where L_1 = stare_wind_speed x "
            "variance_window_s lies in the inertial subrange, well below the integral scale "
            "L_V of w (integral_scale of the turbulence product): on exact von Karman "
            "statistics eps is 0.86 of the truth at L_1 = 0.4 L_V and 0.75 at L_1 = 1.2 L_V "
            "(median); it is biased low where L_1 is not small against L_V"
        ),
        references=OCONNOR_2010,
    ),
    "epsilon_stare_standard_error": VarMeta(
        "standard error of the stare dissipation rate",
        "m2 s-3",
        comment=(
            "1.5 eps SE(sigma_v^2)/sigma_v^2 (SE: scatter of the variances of the "
            "variance windows in the product window over the square root of their number) "
            "and SE(U)/U combined"
        ),
        coverage_content_type="qualityInformation",
    ),
    "stare_flag": VarMeta(
        "stare dissipation-rate quality flag (bits combine; 0 = good)",
        "1",
        flag_masks=(1, 2, 4, 8),
        flag_meanings="no_wind too_few_samples noise_dominated wind_far_in_time",
        comment=(
            "0 good; bit 1 no VAD wind this day (eps NaN); bit 2 fewer valid rays than "
            "stare.min_samples, or no variance window with 3 valid rays (eps NaN); bit 4 "
            "variance not above the noise variance (eps NaN); bit 8 the nearest VAD is more "
            "than stare.max_wind_gap_s away"
        ),
        coverage_content_type="qualityInformation",
    ),
    # ---------------------------------------------------------------- sonic SF product
    "sf_type": VarMeta(
        "structure-function type",
        "1",
        flag_values=(0, 1, 2, 3),
        flag_meanings="none linear parabolic parabolic_then_linear",
        references=GLADKIKH_2014 + ", eqs. 4-6",
    ),
    "r_min": VarMeta("smallest lag of the fit", "m", references=GLADKIKH_2014),
    "r_max": VarMeta("largest lag of the fit", "m", references=GLADKIKH_2014),
    "r_s": VarMeta(
        "type 3: lag of the change from the parabolic to the linear part, (r_p + r_l)/2",
        "m",
        references=GLADKIKH_2014 + ", eq. 10",
    ),
    "k_d": VarMeta("determination coefficient of the fit", "1", references=GLADKIKH_2014),
    "mean_horizontal_wind": VarMeta(
        "mean horizontal wind speed of the window", "m s-1", "wind_speed"
    ),
    "sf_lag": VarMeta("lag number j of the sonic structure function (time lag j/f_d)", "1"),
    "component": VarMeta("wind component: longitudinal V_1, transverse V_2, vertical V_3", "1"),
    "window": VarMeta("analysis window index", "1"),
    "sf_b": VarMeta(
        "type 1: intercept b of lg D_n = b + mu lg r", "1", references=GLADKIKH_2014 + ", eq. 4"
    ),
    "sf_mu": VarMeta(
        "type 1: slope mu of lg D_n = b + mu lg r", "1", references=GLADKIKH_2014 + ", eq. 4"
    ),
    "sf_a0": VarMeta(
        "type 2: coefficient a0 of lg D_n = a0 + a1 x + a2 x^2",
        "1",
        references=GLADKIKH_2014 + ", eq. 5",
    ),
    "sf_a1": VarMeta(
        "type 2: coefficient a1 of lg D_n = a0 + a1 x + a2 x^2",
        "1",
        references=GLADKIKH_2014 + ", eq. 5",
    ),
    "sf_a2": VarMeta(
        "type 2: coefficient a2 of lg D_n = a0 + a1 x + a2 x^2",
        "1",
        references=GLADKIKH_2014 + ", eq. 5",
    ),
    "sf_d0": VarMeta(
        "type 3: coefficient d0 of the parabolic part", "1", references=GLADKIKH_2014 + ", eq. 6"
    ),
    "sf_d1": VarMeta(
        "type 3: coefficient d1 of the parabolic part", "1", references=GLADKIKH_2014 + ", eq. 6"
    ),
    "sf_d2": VarMeta(
        "type 3: coefficient d2 of the parabolic part", "1", references=GLADKIKH_2014 + ", eq. 6"
    ),
    "sf_c": VarMeta(
        "type 3: intercept c of the linear part lg D_n = c + gamma x",
        "1",
        references=GLADKIKH_2014 + ", eq. 6",
    ),
    "sf_gamma": VarMeta(
        "type 3: slope gamma of the linear part lg D_n = c + gamma x",
        "1",
        references=GLADKIKH_2014 + ", eq. 6",
    ),
    "r_p": VarMeta(
        "type 3: end lag r_p of the parabolic part", "m", references=GLADKIKH_2014 + ", eq. 6"
    ),
    "r_l": VarMeta(
        "type 3: start lag r_l of the linear part", "m", references=GLADKIKH_2014 + ", eq. 6"
    ),
    "structure_constant": VarMeta(
        "C = 10^beta D(r_N) of D(r) = C F(r) r_n^alpha",
        "m2 s-2",
        references=GLADKIKH_2014 + ", eq. 7",
    ),
    "sf_at_normalisation_lag": VarMeta(
        "structure function at the lag nearest r_N", "m2 s-2", references=GLADKIKH_2014 + ", eq. 3"
    ),
    "r_normalisation": VarMeta(
        "lag r_j nearest r_N used for the normalisation", "m", references=GLADKIKH_2014 + ", eq. 3"
    ),
    "valid_fraction": VarMeta("fraction of the window's samples that are valid", "1"),
    "window_flag": VarMeta(
        "sonic window flag (bits combine)",
        "1",
        flag_masks=(1, 2, 4),
        flag_meanings="too_few_valid_samples strong_wind_r_min_above_r_n calm_lags_below_r_n",
        comment=(
            "0 analysed; bit 1 too few valid samples; bit 2 r_min > r_N (strong wind); "
            "bit 4 largest lag < r_N (calm)"
        ),
    ),
    "lag_distance": VarMeta(
        "spatial lag r_j = j V_h / f_d", "m", references=GLADKIKH_2014 + ", eq. 2"
    ),
    "normalised_sf": VarMeta(
        "normalised structure function D_n(r_j)", "1", references=GLADKIKH_2014 + ", eq. 3"
    ),
    "normalised_sf_fit": VarMeta(
        "fitted model of the normalised structure function up to r_max",
        "1",
        references=GLADKIKH_2014 + ", eqs. 4-6",
    ),
    "sample_flag": VarMeta(
        "sonic sample flag (bits combine)",
        "1",
        flag_masks=(1, 2, 4),
        flag_meanings="instrument_diagnostic spike missing_or_not_finite",
        comment=(
            "0 good; bit 1 non-zero instrument diagnostic; bit 2 spike; bit 4 missing or not finite"
        ),
    ),
    # ---------------------------------------------------------------- sonic dataset
    "temperature": VarMeta("sonic temperature", "degC", "virtual_temperature"),
    "diagnostic": VarMeta("instrument diagnostic word (0 = good)", "1"),
    # ---------------------------------------------------------------- Monte-Carlo product
    "epsilon_rel_error": VarMeta(
        "relative RMS error of the dissipation rate estimate", "1", references=BANAKH_1999
    ),
    "variance_rel_error": VarMeta(
        "relative RMS error of the velocity variance estimate", "1", references=BANAKH_1999
    ),
    "integral_scale_rel_error": VarMeta(
        "relative RMS error of the integral scale estimate", "1", references=BANAKH_1999
    ),
    "epsilon_mean_ratio": VarMeta(
        "mean over realisations of the estimated to the true dissipation rate (bias)",
        "1",
        references=BANAKH_1999,
    ),
    "rays_per_scan_used": VarMeta(
        "mean number of spectra per scan kept (peak velocity not below the threshold)", "1"
    ),
    "true_epsilon": VarMeta(
        "dissipation rate of the simulation, 1.33 sigma_V^3/L_V",
        "m2 s-3",
        references=BANAKH_1999 + ", eq. 19",
    ),
    "true_velocity_variance": VarMeta("velocity variance sigma_V^2 of the simulation", "m2 s-2"),
    "true_integral_scale": VarMeta("integral scale L_V of the simulation", "m"),
    "true_wind_speed": VarMeta("mean horizontal wind speed of the simulation", "m s-1"),
    "reference_direction": VarMeta(
        "wind direction from a reference instrument (wind vane), from which the wind blows",
        "degree",
        "wind_from_direction",
        comment="resolves the 180 degree ambiguity of homodyne cw lidars",
    ),
    # ---------------------------------------------------------------- turbulence (stages
    # structure/epsilon): block quantities
    "radial_velocity_variance": VarMeta(
        "variance of the radial-velocity deviations V'_L from the block-mean wind "
        "(noise and volume averaging not corrected)",
        "m2 s-2",
        references=SMALIKHO_2020 + ", eq. 1",
    ),
    "azimuth_step": VarMeta("azimuth step dtheta between rays", "degree"),
    "scan_period": VarMeta("duration T_scan of one 360 degree rotation", "s"),
    "scan_interval": VarMeta(
        "median time between the starts of consecutive scans of the block", "s"
    ),
    "epsilon_fit": VarMeta(
        "turbulent kinetic energy dissipation rate from the least-squares fit of "
        "eps^(2/3) A_2 + 2 sigma_e^2 over all lags (method 2)",
        "m2 s-3",
        references=SMALIKHO_2020 + ", eqs. 4, 15",
    ),
    # ---------------------------------------------------------------- wind-record product
    "wind_speed_std": VarMeta(
        "standard deviation of the horizontal wind speed over the averaging interval", "m s-1"
    ),
    "wind_speed_min": VarMeta("minimum horizontal wind speed in the averaging interval", "m s-1"),
    "wind_speed_max": VarMeta("maximum horizontal wind speed in the averaging interval", "m s-1"),
    "n_packets": VarMeta("number of scan packets (1-s rotations) in the average", "1"),
    "data_availability": VarMeta("proportion of valid measurements in the average", "%"),
    "rain_percent": VarMeta("proportion of packets with rain", "%"),
    "raining": VarMeta("rain detected by the instrument (0 no, 1 yes)", "1"),
    "turbulence_intensity": VarMeta(
        "turbulence intensity as measured (standard deviation over mean of the horizontal "
        "wind speed)",
        "1",
    ),
    "volume_averaging_ratio": VarMeta(
        "predicted ratio of the lidar to the cup standard deviation of the wind speed",
        "1",
        references=WAGNER_DTU + ", eqs. 9-11",
    ),
    "turbulence_intensity_corrected": VarMeta(
        "turbulence intensity corrected for the volume averaging of the conically scanning "
        "cw lidar",
        "1",
        references=WAGNER_DTU + ", eqs. 9-11",
    ),
    "turbulence_parameter": VarMeta(
        "turbulence parameter TP: standard deviation of the radial-velocity residuals about "
        "the fitted cosine over one rotation divided by the mean wind speed",
        "1",
        references=WAGNER_DTU + ", eq. 8",
    ),
}


def apply_metadata(ds: xr.Dataset, table: Mapping[str, VarMeta] = VARIABLES) -> xr.Dataset:
    """Attach the declared CF attributes to every variable and coordinate of ``ds``.

    Attributes already set by a stage (method, parameters, references) are kept;
    the declared ``long_name``/``units``/``standard_name`` take precedence.

    Parameters
    ----------
    ds : xarray.Dataset
    table : mapping, optional
        The metadata table (default: :data:`VARIABLES`).

    Returns
    -------
    xarray.Dataset
        A shallow copy with attributes set.
    """
    out = ds.copy()
    for name in list(out.variables):
        meta = table.get(str(name))
        if meta is None:
            continue
        attrs = dict(out[name].attrs)
        attrs.update(meta.attrs())
        attrs.update(_derived_attrs(str(name), meta, is_coord=name in out.coords))
        for key in ("flag_values", "flag_masks"):
            if key in attrs and out[name].dtype.kind in "iu":
                attrs[key] = np.asarray(attrs[key], dtype=out[name].dtype)
        if name == "time":
            attrs.pop("units", None)  # set through the encoding by the writer
        out[name].attrs = attrs
    return out


def _derived_attrs(name: str, meta: VarMeta, *, is_coord: bool) -> dict[str, str]:
    """ACDD attributes that follow from the kind of variable (flags, counts, coordinates)."""
    out: dict[str, str] = {}
    if is_coord:
        out["coverage_content_type"] = "coordinate"
    elif "flag" in name or name == "sf_type":
        out["coverage_content_type"] = "qualityInformation"
        if meta.standard_name is None and name != "sf_type":
            out["standard_name"] = "status_flag"
    elif name.startswith("n_"):
        out["coverage_content_type"] = "auxiliaryInformation"
        if meta.standard_name is None:
            out["standard_name"] = "number_of_observations"
    return out


def undeclared_variables(ds: xr.Dataset, table: Mapping[str, VarMeta] = VARIABLES) -> list[str]:
    """Names of the variables and coordinates of ``ds`` that have no declaration."""
    return sorted(str(n) for n in ds.variables if str(n) not in table)
