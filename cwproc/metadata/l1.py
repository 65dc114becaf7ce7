"""Declarations of the Doppler lidar L1 product and of the Cloudnet layout's names.

Part of :mod:`cwproc.metadata` (the one home of names, units and flags), kept
apart for its size; :data:`L1_VARIABLES` is merged into its ``VARIABLES``.
"""

from __future__ import annotations

from cwproc.metadata.canonical import VarMeta
from cwproc.references import (
    DOPPY,
    MANNINEN_2016,
    PEARSON_2009,
    PENTIKAINEN_2020,
    VAD_WIND,
    VAKKARI_2021,
)

#: CF standard name of the attenuated backscatter (m-1 sr-1)
BETA_STANDARD_NAME = "volume_attenuated_backwards_scattering_function_in_air"

L1_VARIABLES: dict[str, VarMeta] = {
    # ------------------------------------------------- doppler_lidar (L1) product
    "snr_error": VarMeta(
        "standard deviation of the noise signal-to-noise ratio of the ray",
        "1",
        comment="1.4826 MAD of the noise gates beyond the near range, signal gates removed",
        references=MANNINEN_2016,
    ),
    "radial_velocity_screened": VarMeta(
        "radial velocity of the gates screened as signal (positive away from the lidar)",
        "m s-1",
        "radial_velocity_of_scatterers_away_from_instrument",
        comment="NaN where doppler_lidar_flag says noise (see screening_method)",
    ),
    "radial_velocity_error": VarMeta(
        "standard deviation of the radial velocity estimate predicted from the SNR",
        "m s-1",
        "radial_velocity_of_scatterers_away_from_instrument standard_error",
        comment="NaN where the SNR is not positive",
        references=PEARSON_2009 + ", eq. 3",
    ),
    "beta_error": VarMeta(
        "standard error of the attenuated backscatter coefficient from the SNR noise",
        "m-1 sr-1",
        BETA_STANDARD_NAME + " standard_error",
        comment="random part only; the calibration of the lidar constants is not included",
        references=PENTIKAINEN_2020,
    ),
    "beta_screened": VarMeta(
        "attenuated backscatter coefficient of the gates screened as signal",
        "m-1 sr-1",
        BETA_STANDARD_NAME,
        references=PENTIKAINEN_2020 + ", eqs. 1-3",
    ),
    "doppler_lidar_flag": VarMeta(
        "screening flag of the Doppler lidar gates (bits combine; 0 = good)",
        "1",
        comment=(
            "0 good; bit 1 near range; bit 2 box-mean SNR below the noise threshold; bit 4 "
            "velocity texture above the threshold; bit 8 not finite; bit 16 no "
            "cross-polarised ray paired (depolarisation only). A gate with bit 2 is still "
            "signal when its SNR is positive and bit 4 is not set"
        ),
        flag_masks=(1, 2, 4, 8, 16),
        flag_meanings="near_range low_snr velocity_texture not_finite no_cross_ray",
        references=f"{MANNINEN_2016}; {DOPPY}",
    ),
    "snr_cross": VarMeta(
        "signal-to-noise ratio of the paired cross-polarised ray", "1", references=VAKKARI_2021
    ),
    "beta_cross": VarMeta(
        "attenuated backscatter coefficient of the cross-polarised channel",
        "m-1 sr-1",
        BETA_STANDARD_NAME,
        references=PENTIKAINEN_2020,
    ),
    "depolarisation": VarMeta(
        "linear depolarisation ratio (cross- over co-polarised backscatter, minus the "
        "polariser bleed-through)",
        "1",
        references=VAKKARI_2021 + ", eq. 1",
    ),
    "depolarisation_error": VarMeta(
        "standard error of the linear depolarisation ratio from the SNR noise of both rays",
        "1",
        references=VAKKARI_2021,
    ),
    "depolarisation_screened": VarMeta(
        "linear depolarisation ratio of the gates screened as signal",
        "1",
        references=VAKKARI_2021 + ", eq. 1",
    ),
    "cross_time": VarMeta("time of the paired cross-polarised ray (UTC)", None, "time"),
    "cross_floor_refit": VarMeta(
        "noise floor of the paired cross-polarised ray refitted on the co ray's noise gates "
        "(median over range; NaN: not refitted)",
        "1",
        references=MANNINEN_2016,
    ),
    # ----------------------- names of the Cloudnet layout (products/cloudnet.py)
    "beta_raw": VarMeta(
        "attenuated backscatter coefficient, not screened",
        "m-1 sr-1",
        BETA_STANDARD_NAME,
        comment="cwproc beta",
        references=PENTIKAINEN_2020,
    ),
    "depolarisation_raw": VarMeta(
        "linear depolarisation ratio, not screened", "1", references=VAKKARI_2021
    ),
    "beta_cross_raw": VarMeta(
        "attenuated backscatter coefficient of the cross-polarised channel, not screened",
        "m-1 sr-1",
        BETA_STANDARD_NAME,
        references=PENTIKAINEN_2020,
    ),
    "wavelength": VarMeta(
        "laser wavelength", "m", "radiation_wavelength", references=PENTIKAINEN_2020
    ),
    "pulses_per_ray": VarMeta(
        "pulses accumulated per ray",
        "1",
        coverage_content_type="auxiliaryInformation",
        references="Halo Photonics Stream Line .hpl header 'Pulses/ray'",
    ),
    "polariser_bleed_through": VarMeta(
        "polariser bleed-through of the depolarisation ratio", "1", references=VAKKARI_2021
    ),
    "uwind": VarMeta(
        "eastward wind where the VAD fit is good",
        "m s-1",
        "eastward_wind",
        comment="cwproc u where qc_flag is 0, beyond the near range",
        references=VAD_WIND,
    ),
    "vwind": VarMeta(
        "northward wind where the VAD fit is good",
        "m s-1",
        "northward_wind",
        comment="cwproc v where qc_flag is 0, beyond the near range",
        references=VAD_WIND,
    ),
    "uwind_raw": VarMeta(
        "eastward wind, every fitted value",
        "m s-1",
        "eastward_wind",
        comment="cwproc u",
        references=VAD_WIND,
    ),
    "vwind_raw": VarMeta(
        "northward wind, every fitted value",
        "m s-1",
        "northward_wind",
        comment="cwproc v",
        references=VAD_WIND,
    ),
}
