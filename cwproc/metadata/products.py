"""One declaration per variable that cwproc writes: CF-1.10 attributes of every product.

The only home of names, units, flags and citations of the products. The canonical
input variables (scan, wind-record and sonic datasets) are declared in
:mod:`cwproc.metadata.canonical`, whose entries are taken here; the product variables are
declared below, and :data:`PRODUCT_VARIABLES` holds what differs between products
(the bits of ``qc_flag`` of the VAD wind and of the wind-record product, citations).
Stages never write ``units``/``standard_name``/``long_name``/``references``/flag
attributes themselves (a test scans them): the decorator :func:`cwproc.metadata.described`
attaches the declared ones to what a stage returns, and :func:`apply_metadata`, called
with the product's name by the NetCDF writer and by :func:`cwproc.retrieve`, attaches
them again and keeps what records *what was done* (method, parameters). A test checks that every
variable of every product is declared here.

To add a variable: add one :class:`VarMeta` entry to ``_PRODUCT_VARIABLES`` (keep the
table grouped by product).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import xarray as xr

from cwproc.errors import CwprocError
from cwproc.metadata.canonical import (
    SCAN_VARIABLES,
    SONIC_VARIABLES,
    WIND_RECORD_VARIABLES,
    VarMeta,
    attach_attrs,
)
from cwproc.metadata.dbs import DBS_OVERRIDES, DBS_VARIABLES
from cwproc.metadata.l1 import BETA_STANDARD_NAME, L1_VARIABLES
from cwproc.metadata.sonic import (
    COMPARISON_VARIABLES,
    SONIC_TURBULENCE_OVERRIDES,
    SONIC_TURBULENCE_VARIABLES,
)
from cwproc.references import (
    BANAKH_1999,
    GLADKIKH_2014,
    OCONNOR_2010,
    PENTIKAINEN_2020,
    SATHE_2011,
    SMALIKHO_2020,
    VAD_ACCURACY,
    VAD_WIND,
    WAGNER_DTU,
)


def _gladkikh(long_name: str, units: str, equation: str) -> VarMeta:
    """A sonic SF variable defined by ``equation`` of Gladkikh et al. (2014)."""
    return VarMeta(long_name, units, references=f"{GLADKIKH_2014}, {equation}")


_TYPE_FORMS = (
    (1, "eq. 4", "lg D_n = b + mu lg r", {"b": "intercept b", "mu": "slope mu"}),
    (2, "eq. 5", "lg D_n = a0 + a1 x + a2 x^2", {f"a{k}": f"coefficient a{k}" for k in range(3)}),
    (3, "eq. 6", "the parabolic part", {f"d{k}": f"coefficient d{k}" for k in range(3)}),
    (
        3,
        "eq. 6",
        "the linear part lg D_n = c + gamma x",
        {"c": "intercept c", "gamma": "slope gamma"},
    ),
)
#: fitted coefficients sf_<name> of the three structure-function types
_SF_COEFFICIENTS: dict[str, VarMeta] = {
    f"sf_{name}": _gladkikh(f"type {t}: {what} of {form}", "1", eq)
    for t, eq, form, names in _TYPE_FORMS
    for name, what in names.items()
}


#: the product variables (the canonical input variables are added below)
_PRODUCT_VARIABLES: dict[str, VarMeta] = {
    "altitude": VarMeta(
        "altitude of the instrument above mean sea level",
        "m",
        "altitude",
        positive="up",
        coverage_content_type="coordinate",
    ),
    "lag": VarMeta("azimuth lag number l of the structure function", "1"),
    "qc_flag_radial": VarMeta(
        "radial velocity screening flag (bits combine; 0 = good)",
        "1",
        comment="0 good; bit 1 SNR below threshold; bit 2 robust outlier; bit 4 not finite",
        flag_masks=(1, 2, 4),
        flag_meanings="low_snr outlier not_finite",
        references=SMALIKHO_2020 + ", eq. 1",
    ),
    # ------------------------------------------------ scan dataset: stage background
    "snr_uncorrected": VarMeta("signal-to-noise ratio as given by the instrument", "1"),
    "noise_floor": VarMeta("median noise floor F of the background correction", "1"),
    "background_time": VarMeta(
        "time of the background measurement that corrected the ray (UTC)", None, "time"
    ),
    **L1_VARIABLES,  # the Doppler lidar L1 product and the Cloudnet layout
    # ---------------------------------------------------------------- wind product
    "u": VarMeta("eastward wind", "m s-1", "eastward_wind"),
    "v": VarMeta("northward wind", "m s-1", "northward_wind"),
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
        comment=(
            "the bits depend on the product: VAD wind: 1 too few rays, 2 azimuth gap too "
            "large, 4 bad fit; wind records: 1 too few packets, 4 missing value, 8 rain"
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
        flag_masks=(1, 2, 4, 8, 16, 32, 64),
        flag_meanings=(
            "too_few_pairs lag_beyond_inertial_range mu_beyond_method1 fit_failed "
            "partial_block noise_predicted integral_scale_unresolved"
        ),
        comment=(
            "0 good; bit 1 too few pairs; bit 2 lag beyond the inertial range; "
            "bit 4 mu beyond method 1 validity (epsilon_method1 is kept); bit 8 fit failed; "
            "bit 16 partial block (fewer than half the requested scans per block); bit 32 "
            "the fitted noise intercept is not determined (its standard error above half "
            "the predicted 2 sigma_e^2 or sigma_e below half the predicted one, and fit "
            "and prediction not 4 standard errors of their difference apart (both "
            "uncertainties); or negative): noise_std is the prediction from the SNR times "
            "noise_std_calibration where that was applied, used in the fit; bit 64 the "
            "integral scale is below the smallest resolved separation (transverse "
            "sampling dy at lag 1): epsilon, velocity_variance and integral_scale are "
            "kept but not good"
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
    "noise_std_calibration": VarMeta(
        "factor of the SNR-predicted instrumental error sigma_e that the structure "
        "functions of the day measure",
        "1",
        comment=(
            "k = sqrt of the median over the cells (block x height) of the free fitted "
            "noise intercept 2 sigma_e^2 (generalised least squares with the covariance of "
            "D pooled over the height's blocks) over the predicted one; applied to "
            "noise_std_predicted where the data do not determine sigma_e (flag 32) when k "
            "differs from 1 by more than 2 standard errors and 5 %, explains the cells (robust "
            "spread of their intercepts about k^2 at most 3 of their errors) and was learnt "
            "from at least 10 blocks to 10 % (attribute applied); NaN with fewer than 10 "
            "such cells; "
            "attribute standard_error: that of the median ratio, sqrt(pi/2) 1.4826 MAD / "
            "sqrt(cells), over 2 k"
        ),
        references=SMALIKHO_2020 + ", eq. 4; Pearson G., Davies F., Collier C. (2009), "
        "J. Atmos. Oceanic Technol. 26, 240-250, eq. 3",
        coverage_content_type="qualityInformation",
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
        "covariance of the block means of (D_L(1), ..., D_L(L), variance of V'_L): "
        "jackknife over the scans, the block-mean VAD wind refitted without each",
        "m4 s-4",
        coverage_content_type="qualityInformation",
    ),
    "wind_to_direction": VarMeta(
        "direction the block-mean wind blows towards", "degree", "wind_to_direction"
    ),
    "scan_start_angle": VarMeta(
        "azimuth of the first ray of the block from the direction the block-mean wind "
        "blows towards, in the scan's sense of rotation",
        "degree",
    ),
    "pair_azimuth_weights": VarMeta(
        "share of the ray pairs of each lag at each azimuth node of the wind's angle from "
        "the scan direction (sectors, gaps and the positions a scan's pairs leave out)",
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
        references=OCONNOR_2010 + ", eqs. 1-4",
    ),
    "epsilon_stare_standard_error": VarMeta(
        "standard error of the stare dissipation rate",
        "m2 s-3",
        comment=(
            "1.5 eps SE(sigma_v^2)/sigma_v^2 and SE(U)/U combined; SE(sigma_v^2) is the "
            "standard deviation of the mean window variance of Gaussian rays sampled as "
            "these were (their times, eps, U and the noise; the variance of a quadratic "
            "form), valid for any number of variance windows. The probe used is in the "
            "global attributes probe_delta_r_m, probe_delta_p_m and their *_source"
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
    "r_s": _gladkikh(
        "type 3: lag of the change from the parabolic to the linear part, (r_p + r_l)/2",
        "m",
        "eq. 10",
    ),
    "k_d": VarMeta("determination coefficient of the fit", "1", references=GLADKIKH_2014),
    "mean_horizontal_wind": VarMeta(
        "mean horizontal wind speed of the window", "m s-1", "wind_speed"
    ),
    "sf_lag": VarMeta("lag number j of the sonic structure function (time lag j/f_d)", "1"),
    "component": VarMeta("wind component: longitudinal V_1, transverse V_2, vertical V_3", "1"),
    "window": VarMeta("analysis window index", "1"),
    **_SF_COEFFICIENTS,
    "r_p": _gladkikh("type 3: end lag r_p of the parabolic part", "m", "eq. 6"),
    "r_l": _gladkikh("type 3: start lag r_l of the linear part", "m", "eq. 6"),
    "structure_constant": _gladkikh(
        "C = 10^beta D(r_N) of D(r) = C F(r) r_n^alpha", "m2 s-2", "eq. 7"
    ),
    "sf_at_normalisation_lag": _gladkikh(
        "structure function at the lag nearest r_N", "m2 s-2", "eq. 3"
    ),
    "r_normalisation": _gladkikh("lag r_j nearest r_N used for the normalisation", "m", "eq. 3"),
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
    "lag_distance": _gladkikh("spatial lag r_j = j V_h / f_d", "m", "eq. 2"),
    "normalised_sf": _gladkikh("normalised structure function D_n(r_j)", "1", "eq. 3"),
    "normalised_sf_fit": _gladkikh(
        "fitted model of the normalised structure function up to r_max", "1", "eqs. 4-6"
    ),
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
    "n_packets": VarMeta("number of scan packets (1-s rotations) in the average", "1"),
    "volume_averaging_ratio": VarMeta(
        "predicted ratio of the lidar to the cup standard deviation of the wind speed",
        "1",
        references=WAGNER_DTU + ", eqs. 9-11",
    ),
    "turbulence_intensity_corrected": VarMeta(
        "turbulence intensity corrected for the lidar's measurement: volume averaging of the "
        "conically scanning cw lidar, or noise, pulsed-probe averaging and DBS "
        "cross-contamination of a WindCube's lines of sight (see method)",
        "1",
        references=WAGNER_DTU + ", eqs. 9-11 (cw); " + SATHE_2011 + " (DBS)",
    ),
    **{
        f"{c}_variance_dbs": VarMeta(
            f"variance of the {what} over the interval from the DBS lines of sight, corrected "
            "for noise, pulsed-probe averaging and DBS cross-contamination",
            "m2 s-2",
            references=SATHE_2011,
        )
        for c, what in (
            ("u", "eastward wind"),
            ("v", "northward wind"),
            ("w", "upward air velocity"),
        )
    },
    "dbs_flag": VarMeta(
        "quality of the DBS statistics of WindCube lines of sight (bits combine)",
        "1",
        flag_masks=(1, 2, 4),
        flag_meanings="few_beam_cycles low_cnr inhomogeneous_flow",
        comment="0 good; bit 1 fewer complete beam cycles than [dbs] min_cycles_percent; "
        "bit 2 median CNR within 3 dB of the threshold (the noise law does not hold); bit 4 "
        "w of the inclined beams differs from the vertical beam's by more than [dbs] "
        "max_w_mismatch (inhomogeneous flow, complex terrain: DBS does not hold)",
        coverage_content_type="qualityInformation",
    ),
    "turbulence_parameter": VarMeta(
        "turbulence parameter TP: standard deviation of the radial-velocity residuals about "
        "the fitted cosine over one rotation divided by the mean wind speed",
        "1",
        references=WAGNER_DTU + ", eq. 8",
    ),
}


#: every variable cwproc writes: the canonical input variables and the product variables
VARIABLES: dict[str, VarMeta] = {
    **SCAN_VARIABLES,
    **WIND_RECORD_VARIABLES,
    **{k: SONIC_VARIABLES[k] for k in ("temperature", "diagnostic", "sample_flag")},
    **_PRODUCT_VARIABLES,
    **SONIC_TURBULENCE_VARIABLES,
    **COMPARISON_VARIABLES,
    **DBS_VARIABLES,
}

_VAD_ERROR_REFERENCES = f"{VAD_ACCURACY}, section 4"


def _qc_bits(bits: dict[int, str], comment: str) -> VarMeta:
    """``qc_flag`` of one product: its bit masks -> meanings, and their description."""
    return replace(
        VARIABLES["qc_flag"],
        flag_masks=tuple(bits),
        flag_meanings=" ".join(bits.values()),
        comment=comment,
    )


#: per product, the declarations that differ from :data:`VARIABLES` (flag bits, citations)
PRODUCT_VARIABLES: dict[str, dict[str, VarMeta]] = {
    "wind": {
        "qc_flag": _qc_bits(
            {1: "too_few_rays", 2: "azimuth_gap_too_large", 4: "bad_fit"},
            "0 good; bit 1 too few rays; bit 2 azimuth gap too large; bit 4 bad fit "
            "(see bad_fit_definition)",
        ),
        **{
            name: replace(VARIABLES[name], references=VAD_WIND)
            for name in ("u", "v", "w", "wind_speed", "wind_direction")
        },
        **{
            name: replace(VARIABLES[name], references=_VAD_ERROR_REFERENCES)
            for name in ("u_error", "v_error", "w_error")
        },
    },
    "wind_record": {
        "qc_flag": _qc_bits(
            {1: "too_few_samples", 4: "missing_value", 8: "rain"},
            "0 good; bit 1 too few packets or too low data availability; bit 4 missing "
            "value; bit 8 too many packets with rain",
        ),
    },
    "sf": {
        "time": replace(VARIABLES["time"], comment="start of the analysis window"),
        "wind_direction": replace(
            VARIABLES["wind_direction"],
            long_name="direction of the window-mean wind (from which it blows, clockwise "
            "from north)",
            comment=(
                "mean u, v of the window in the instrument frame turned by [sonic] "
                "orientation_deg, the azimuth of the sonic's +x axis"
            ),
        ),
    },
}

PRODUCT_VARIABLES["sonic_turbulence"] = SONIC_TURBULENCE_OVERRIDES
PRODUCT_VARIABLES["lidar_sonic"] = {
    "time": SONIC_TURBULENCE_OVERRIDES["time"],
    "mean_wind_speed": SONIC_TURBULENCE_VARIABLES["mean_wind_speed"],
}

_ASL_HEIGHT = VarMeta(
    "height above mean sea level",
    "m",
    "altitude",
    positive="up",
    axis="Z",
    coverage_content_type="coordinate",
)
_CLOUDNET_REFERENCES = "ACTRIS Cloudnet file conventions (https://docs.cloudnet.fmi.fi)"
#: the Cloudnet layout's files (:mod:`cwproc.products.cloudnet`): their names, not cwproc's
PRODUCT_VARIABLES["doppler_lidar"] = {
    "beta": replace(
        VARIABLES["beta"], standard_name=BETA_STANDARD_NAME, references=PENTIKAINEN_2020
    ),
}
PRODUCT_VARIABLES["doppler-lidar"] = {
    "height": replace(_ASL_HEIGHT, axis=None),
    "v": VarMeta(
        "Doppler velocity of the gates screened as signal (positive away from the lidar)",
        "m s-1",
        "radial_velocity_of_scatterers_away_from_instrument",
        comment="cwproc radial_velocity_screened",
    ),
    "beta": replace(VARIABLES["beta_screened"], comment="cwproc beta_screened"),
    "depolarisation": VARIABLES["depolarisation_screened"],
    "beta_cross": replace(VARIABLES["beta_cross"], comment="screened as beta"),
}
PRODUCT_VARIABLES["doppler-lidar-wind"] = {"height": _ASL_HEIGHT}
for _table in (PRODUCT_VARIABLES["doppler-lidar"], PRODUCT_VARIABLES["doppler-lidar-wind"]):
    for _name, _meta in list(_table.items()):
        if _meta.references is None:
            _table[_name] = replace(_meta, references=_CLOUDNET_REFERENCES)

#: every product cwproc writes: the VAD wind, the wind of instrument wind records, the
#: turbulence of conical scans, the vertical-stare statistics, the sonic structure-function
#: types and the Monte-Carlo error study
PRODUCTS: tuple[str, ...] = (
    "wind",
    "wind_record",
    "turbulence",
    "stare",
    "doppler_lidar",
    "doppler-lidar",
    "doppler-lidar-wind",
    "sf",
    "sonic_turbulence",
    "lidar_sonic",
    "montecarlo",
)


#: declarations of intermediate datasets that are no product (:func:`described` of a
#: stage whose output only feeds another stage): what differs from :data:`VARIABLES`
INTERMEDIATE_VARIABLES: dict[str, dict[str, VarMeta]] = {"dbs": DBS_OVERRIDES}


def product_table(product: str) -> dict[str, VarMeta]:
    """The declarations of ``product``: :data:`VARIABLES` with its own entries over them.

    Raises
    ------
    CwprocError
        ``product`` is not one of :data:`PRODUCTS`.
    """
    if product not in PRODUCTS:
        raise CwprocError(
            f"unknown product {product!r}: the metadata declares {', '.join(PRODUCTS)}"
        )
    return {**VARIABLES, **PRODUCT_VARIABLES.get(product, {})}


def apply_metadata(ds: xr.Dataset, *, product: str) -> xr.Dataset:
    """Attach the declared CF attributes to every variable and coordinate of ``ds``.

    The declared attributes (names, units, flags, citations; see
    :data:`cwproc.metadata.canonical.DECLARED_ATTRS`) replace whatever a reader or a stage set;
    the attributes that record what a stage did (method, parameters) are kept.

    Parameters
    ----------
    ds : xarray.Dataset
    product : str
        The product ``ds`` is, one of :data:`PRODUCTS` (the wind of a wind-record unit
        is ``"wind_record"``: its ``qc_flag`` bits differ).

    Returns
    -------
    xarray.Dataset
        A shallow copy with attributes set.

    Raises
    ------
    CwprocError
        ``product`` is not one of :data:`PRODUCTS`.
    """
    return attach_declared(ds, product_table(product))


def attach_declared(
    ds: xr.Dataset, table: Mapping[str, VarMeta], *, flag_arrays: bool = True
) -> xr.Dataset:
    """``ds`` with the declarations of ``table`` and the ACDD attributes they imply.

    :func:`cwproc.metadata.canonical.attach_attrs` (``flag_arrays`` as there), then the
    content type and standard name that follow from the kind of variable (flags,
    counts, coordinates). Used by :func:`apply_metadata` (a product's table) and
    :func:`cwproc.metadata.described` (a stage's output).
    """
    out = attach_attrs(ds, table, flag_arrays=flag_arrays)
    coords = set(out.coords)
    for name, var in out.variables.items():  # Variables: no DataArray built per name
        meta = table.get(str(name))
        if meta is not None:
            var.attrs.update(_derived_attrs(str(name), meta, is_coord=name in coords))
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
