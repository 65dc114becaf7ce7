"""What each product is: its title, summary, keywords and references (ACDD attributes).

The one home of the descriptions of the product files; the variables' own names, units
and flags are in :mod:`cwproc.metadata.products`.
"""

from __future__ import annotations

from dataclasses import dataclass

from cwproc.metadata.sonic import SONIC_TURBULENCE_REFERENCES
from cwproc.references import (
    BANAKH_1999,
    GLADKIKH_2014,
    MANNINEN_2016,
    OCONNOR_2010,
    PEARSON_2009,
    PENTIKAINEN_2020,
    SMALIKHO_2020,
    VAD_ACCURACY,
    VAKKARI_2021,
    WAGNER_DTU,
)


@dataclass(frozen=True)
class ProductDescription:
    """ACDD ``title``, ``summary``, ``keywords`` and ``references`` of one product."""

    title: str
    summary: str
    keywords: str
    references: str


_TITLES = {
    "wind": ("Wind profile", "Horizontal and vertical wind from VAD fits of conical scans"),
    "turbulence": (
        "Turbulence from conical scans",
        "Azimuth structure function, dissipation rate (methods 1 and 2), noise, velocity "
        "variance and integral scale",
    ),
    "stare": (
        "Vertical-velocity statistics and dissipation rate from vertical stares",
        "Mean, variance and skewness of w per window, the noise variance from the SNR, and "
        "the dissipation rate from the variance of w and the VAD wind speed",
    ),
    "doppler_lidar": (
        "Doppler lidar Level 1: backscatter, depolarisation and velocity of vertical stares",
        "Background-corrected SNR, attenuated backscatter with the telescope focus function, "
        "linear depolarisation ratio from paired co- and cross-polarised rays, radial "
        "velocity, their standard errors and a screening flag on intensity and velocity "
        "texture",
    ),
    "doppler-lidar": (
        "Doppler lidar (ACTRIS Cloudnet layout)",
        "Attenuated backscatter, depolarisation ratio and Doppler velocity of vertical "
        "stares in the variable names of Cloudnet's doppler-lidar files",
    ),
    "doppler-lidar-wind": (
        "Doppler lidar wind (ACTRIS Cloudnet layout)",
        "Horizontal wind from VAD fits in the variable names of Cloudnet's "
        "doppler-lidar-wind files",
    ),
    "sf": (
        "Structure-function types of sonic anemometer data",
        "Types (1 line, 2 parabola, 3 parabola then line in lg-lg axes) and fitted "
        "coefficients of the normalised structure functions of the longitudinal, "
        "transverse and vertical wind per 10-min window",
    ),
    "sonic_turbulence": (
        "Turbulence from a sonic anemometer",
        "Dissipation rate from the inertial range of the structure functions (range from "
        "their type), velocity variances, TKE, friction velocity, integral scales with "
        "random errors, despiking and the steady-state and ITC flags per averaging window",
    ),
    "lidar_sonic": (
        "Dissipation rate: lidar against sonic anemometer",
        "The lidar's dissipation rate at the sonic's height averaged over each sonic "
        "window, the sonic's, their ratio with its error, the sonic's stability and wind",
    ),
}
_KEYWORDS = {
    "wind": "Doppler lidar, VAD, wind profile",
    "turbulence": "Doppler lidar, turbulence, dissipation rate, structure function",
    "sf": "sonic anemometer, structure function, turbulence, surface layer",
    "sonic_turbulence": "sonic anemometer, dissipation rate, eddy covariance, quality flags",
    "lidar_sonic": "Doppler lidar, sonic anemometer, dissipation rate, validation",
    "stare": "Doppler lidar, vertical stare, vertical velocity, turbulence, dissipation rate",
    "doppler_lidar": "Doppler lidar, attenuated backscatter, depolarisation ratio, vertical stare",
    "doppler-lidar": "Doppler lidar, attenuated backscatter, depolarisation ratio, Cloudnet",
    "doppler-lidar-wind": "Doppler lidar, VAD, wind profile, Cloudnet",
}
_REFERENCES = {
    "wind": SMALIKHO_2020 + "; " + VAD_ACCURACY,
    "turbulence": SMALIKHO_2020 + "; " + BANAKH_1999,
    "sf": GLADKIKH_2014,
    "sonic_turbulence": SONIC_TURBULENCE_REFERENCES,
    "lidar_sonic": SMALIKHO_2020 + "; " + SONIC_TURBULENCE_REFERENCES,
    "stare": OCONNOR_2010 + "; " + PEARSON_2009,
    "doppler_lidar": f"{PENTIKAINEN_2020}; {VAKKARI_2021}; {MANNINEN_2016}",
    "doppler-lidar": f"{PENTIKAINEN_2020}; {VAKKARI_2021}; {MANNINEN_2016}",
    "doppler-lidar-wind": SMALIKHO_2020 + "; " + VAD_ACCURACY,
}

_WIND_RECORD = ProductDescription(
    "Wind profile (instrument wind records)",
    "Wind speed, direction and turbulence intensity from the instrument's own averages, "
    "with the turbulence intensity corrected for volume averaging",
    "Doppler lidar, wind profile, turbulence intensity",
    WAGNER_DTU,
)


def product_kind(name: str, unit_kind: str) -> str:
    """The product (a key of :data:`cwproc.metadata.products.PRODUCTS`) that product
    ``name`` of a unit of kind ``unit_kind`` is: the ``"wind"`` of instrument wind
    records is ``"wind_record"``, every other product is its name."""
    return "wind_record" if unit_kind == "wind_record" else name


def describe_product(name: str, unit_kind: str) -> ProductDescription:
    """The description of product ``name`` (``"wind"``, ``"turbulence"``, ``"stare"``, ``"sf"``)
    of a unit of kind ``unit_kind`` (``"wind_record"`` for instrument wind records)."""
    if product_kind(name, unit_kind) == "wind_record":
        return _WIND_RECORD
    title, summary = _TITLES.get(name, (name, name))
    return ProductDescription(title, summary, _KEYWORDS.get(name, ""), _REFERENCES.get(name, ""))
