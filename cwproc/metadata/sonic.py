"""Declarations of the sonic turbulence product (stage ``sonic_turbulence``).

Part of :mod:`cwproc.metadata` (the one home of names, units and flags), kept
apart for its size: :data:`SONIC_TURBULENCE_VARIABLES` is merged into its ``VARIABLES``
and :data:`SONIC_TURBULENCE_OVERRIDES` is the product's own table of the names it
shares with other products.
"""

from __future__ import annotations

from cwproc.metadata.canonical import VarMeta
from cwproc.references import GLADKIKH_2014

VICKERS_MAHRT_1997 = (
    "Vickers D., Mahrt L. (1997), Quality control and flux sampling problems for tower and "
    "aircraft data, J. Atmos. Oceanic Technol. 14, 512-526"
)
MAUDER_2013 = (
    "Mauder M. et al. (2013), A strategy for quality and uncertainty assessment of long-term "
    "eddy-covariance measurements, Agric. For. Meteorol. 169, 122-135"
)
FOKEN_WICHURA_1996 = (
    "Foken T., Wichura B. (1996), Tools for quality assessment of surface-based flux "
    "measurements, Agric. For. Meteorol. 78, 83-105"
)
MAUDER_FOKEN_2004 = (
    "Mauder M., Foken T. (2004), Documentation and instruction manual of the eddy covariance "
    "software package TK2, Univ. Bayreuth, Abt. Mikrometeorol., Arbeitsergebnisse 26"
)
WILCZAK_2001 = (
    "Wilczak J.M., Oncley S.P., Stage S.A. (2001), Sonic anemometer tilt correction "
    "algorithms, Boundary-Layer Meteorol. 99, 127-150"
)
LENSCHOW_1994 = (
    "Lenschow D.H., Mann J., Kristensen L. (1994), How long is long enough when measuring "
    "fluxes and other turbulence statistics?, J. Atmos. Oceanic Technol. 11, 661-673"
)
POPE_2000 = "Pope S.B. (2000), Turbulent Flows, Cambridge University Press"
KAIMAL_FINNIGAN_1994 = (
    "Kaimal J.C., Finnigan J.J. (1994), Atmospheric Boundary Layer Flows, Oxford Univ. Press"
)

#: the ACDD ``references`` of the product
SONIC_TURBULENCE_REFERENCES = "; ".join(
    (
        GLADKIKH_2014,
        VICKERS_MAHRT_1997,
        MAUDER_2013,
        WILCZAK_2001,
        FOKEN_WICHURA_1996,
        MAUDER_FOKEN_2004,
        LENSCHOW_1994,
        POPE_2000,
    )
)
_EPS_REFS = f"{POPE_2000}, eqs. 6.28-6.30; fitting range: {GLADKIKH_2014}, eqs. 4-6"

#: variables only the sonic turbulence product has
SONIC_TURBULENCE_VARIABLES: dict[str, VarMeta] = {
    "mean_wind_speed": VarMeta(
        "mean wind speed along the rotated x axis (streamline)", "m s-1", "wind_speed"
    ),
    "yaw_angle": VarMeta(
        "first rotation angle (into the mean wind)", "degree", references=WILCZAK_2001 + ", eq. 22"
    ),
    "pitch_angle": VarMeta(
        "second rotation angle: pitch setting the mean w to zero (double rotation), or the "
        "tilt of the planar-fit normal from the instrument's z axis (planar fit)",
        "degree",
        references=WILCZAK_2001 + ", eqs. 23 and 42",
    ),
    "velocity_variance_error": VarMeta(
        "random error (1 sigma) of the velocity variance, variance sqrt(2 T/T_avg)",
        "m2 s-2",
        references=LENSCHOW_1994,
    ),
    "tke": VarMeta(
        "turbulent kinetic energy per unit mass, half the sum of the three variances",
        "m2 s-2",
        "specific_turbulent_kinetic_energy_of_air",
    ),
    "tke_error": VarMeta(
        "random error (1 sigma) of the turbulent kinetic energy", "m2 s-2", references=LENSCHOW_1994
    ),
    "friction_velocity": VarMeta(
        "friction velocity (<u'w'>^2 + <v'w'>^2)^(1/4)",
        "m s-1",
        references="Weber R.O. (1999), Boundary-Layer Meteorol. 93, 197-209",
    ),
    "friction_velocity_error": VarMeta(
        "random error (1 sigma) of the friction velocity", "m s-1", references=LENSCHOW_1994
    ),
    "integral_time_scale": VarMeta(
        "integral time scale: autocorrelation integrated to its first zero",
        "s",
        references=KAIMAL_FINNIGAN_1994,
    ),
    "integral_length_scale": VarMeta(
        "integral length scale: integral time scale times the mean wind speed (Taylor)",
        "m",
        references=KAIMAL_FINNIGAN_1994,
    ),
    "inertial_range_min": VarMeta(
        "smallest lag of the inertial range used for the dissipation rate",
        "m",
        references=_EPS_REFS,
    ),
    "inertial_range_max": VarMeta(
        "largest lag of the inertial range used for the dissipation rate", "m", references=_EPS_REFS
    ),
    "epsilon_component": VarMeta(
        "turbulent kinetic energy dissipation rate from the second-order structure function "
        "of the component, D = C eps^(2/3) r^(2/3) over the inertial range (C = 2.0 "
        "longitudinal, 8/3 transverse and vertical)",
        "m2 s-3",
        references=_EPS_REFS,
    ),
    "epsilon_component_error": VarMeta(
        "standard error of epsilon_component from its scatter over the sub-windows (batch means)",
        "m2 s-3",
        references=_EPS_REFS,
    ),
    "epsilon_flag": VarMeta(
        "why a component has no dissipation rate",
        "1",
        flag_values=(0, 1, 2),
        flag_meanings="epsilon_given no_structure_function_type no_inertial_range",
        comment="1: the window's structure function was not typed; 2: the typed fit has no run "
        "of at least min_inertial_points lags whose slope is within slope_tolerance of 2/3",
    ),
    "epsilon_error": VarMeta(
        "standard error of epsilon (inverse-variance weighting of the components)",
        "m2 s-3",
        references=_EPS_REFS,
    ),
    "epsilon_spectrum": VarMeta(
        "dissipation rate from the longitudinal spectrum E_11 = C_1 eps^(2/3) k^(-5/3), "
        "C_1 = 0.49, over the inertial range of the longitudinal structure function (check)",
        "m2 s-3",
        references=POPE_2000 + ", eq. 6.246",
    ),
    "spike_fraction": VarMeta(
        "fraction of the samples of the window replaced as spikes",
        "1",
        references=f"{VICKERS_MAHRT_1997}; {MAUDER_2013}, eq. 1",
    ),
    "stability_parameter": VarMeta(
        "stability parameter z/L from the sonic temperature flux (0: no temperature, "
        "neutral assumed)",
        "1",
    ),
    "stationarity_deviation": VarMeta(
        "steady-state test of <u'w'>: deviation of the mean sub-window covariance from the "
        "window's",
        "percent",
        references=FOKEN_WICHURA_1996,
    ),
    "itc_deviation": VarMeta(
        "integral turbulence characteristics test: deviation of sigma_w/u_* from its model",
        "percent",
        references=FOKEN_WICHURA_1996
        + "; models of Foken et al. (2004) and Thomas and Foken (2002)",
    ),
    "itc_deviation_u": VarMeta(
        "integral turbulence characteristics test: deviation of sigma_u/u_* from its model "
        "(not in foken_flag)",
        "percent",
        references=FOKEN_WICHURA_1996
        + "; models of Foken et al. (2004) and Thomas and Foken (2002)",
    ),
    "foken_flag": VarMeta(
        "overall quality flag of the steady-state and ITC tests",
        "1",
        flag_values=(0, 1, 2),
        flag_meanings="high_quality usable bad",
        comment="0: both deviations <= 30 %; 1: both <= 100 %; 2: otherwise (an ITC outside "
        "its models' stability range is not held against the window)",
        references=MAUDER_FOKEN_2004,
    ),
}

#: the product's own declarations of names that other products use too
SONIC_TURBULENCE_OVERRIDES: dict[str, VarMeta] = {
    "epsilon": VarMeta(
        "turbulent kinetic energy dissipation rate from the sonic's structure functions",
        "m2 s-3",
        references=_EPS_REFS,
    ),
    "velocity_variance": VarMeta(
        "variance of the wind component (after despiking, rotation and detrending)", "m2 s-2"
    ),
    "window_flag": VarMeta(
        "sonic turbulence window flag (bits combine)",
        "1",
        flag_masks=(1, 2, 4, 8, 16),
        flag_meanings="too_few_valid_samples spikes_above_1_percent no_epsilon "
        "itc_not_tested spectrum_disagrees",
        comment="0 good; bit 1 too few valid samples; bit 2 more than 1 % spikes in a "
        "component (hard flag of Vickers and Mahrt 1997); bit 4 no component has an inertial "
        "range; bit 8 ITC not tested (no height or stability outside the models); bit 16 "
        "epsilon_spectrum differs from the longitudinal epsilon by more than a factor 2",
    ),
    "wind_direction": VarMeta(
        "direction of the window-mean wind (from which it blows, clockwise from north)",
        "degree",
        "wind_from_direction",
    ),
    "time": VarMeta("time (UTC)", None, "time", comment="start of the averaging window", axis="T"),
}


#: the lidar-against-sonic comparison product (stage ``lidar_sonic``)
COMPARISON_VARIABLES: dict[str, VarMeta] = {
    "lidar_epsilon": VarMeta(
        "dissipation rate of the lidar at the sonic's height: mean of the blocks in the "
        "sonic window",
        "m2 s-3",
    ),
    "lidar_epsilon_standard_error": VarMeta(
        "standard error of lidar_epsilon, sqrt(sum of the blocks' squared errors) / n", "m2 s-3"
    ),
    "n_lidar_blocks": VarMeta("number of lidar blocks (turbulence_flag 0) in the window", "1"),
    "sonic_epsilon": VarMeta(
        "dissipation rate of the sonic anemometer in the window", "m2 s-3", references=_EPS_REFS
    ),
    "sonic_epsilon_standard_error": VarMeta("standard error of sonic_epsilon", "m2 s-3"),
    "lidar_sonic_epsilon_ratio": VarMeta("ratio of the lidar to the sonic dissipation rate", "1"),
    "lidar_sonic_epsilon_ratio_error": VarMeta(
        "standard error of the ratio (relative errors in quadrature)", "1"
    ),
    "lidar_height": VarMeta("height of the lidar gate compared with the sonic", "m"),
}
