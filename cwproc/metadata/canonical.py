"""The canonical input datasets' variables and their CF attributes.

Every reader returns one of three canonical datasets: a scan
dataset (Doppler lidar rays and gates), a wind-record dataset (an instrument's own wind
averages) or a sonic dataset (anemometer samples). Their variables are declared here,
once, as :class:`VarMeta` entries, and :func:`cwproc.io.schema.with_canonical_attrs`
attaches the attributes when a reader builds its dataset, so that
``read_hpl(path).radial_velocity.attrs["units"] == "m s-1"``.

The products' own variables are declared in :mod:`cwproc.metadata.products`, which
takes the entries of this module (one declaration per variable).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Literal

import numpy as np
import xarray as xr

from cwproc.references import SMALIKHO_2020

#: the kinds of canonical dataset the readers return
DatasetKind = Literal["scan", "wind_record", "sonic"]


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


#: attribute names that only a metadata table sets: naming, units, flags, citations
DECLARED_ATTRS = frozenset(f.name for f in fields(VarMeta))

TIME = VarMeta("time (UTC)", None, "time", axis="T", coverage_content_type="coordinate")
HEIGHT = VarMeta(
    "height above the instrument",
    "m",
    "height",
    positive="up",
    axis="Z",
    coverage_content_type="coordinate",
)
LATITUDE = VarMeta(
    "latitude of the instrument",
    "degrees_north",
    "latitude",
    axis="Y",
    coverage_content_type="coordinate",
)
LONGITUDE = VarMeta(
    "longitude of the instrument",
    "degrees_east",
    "longitude",
    axis="X",
    coverage_content_type="coordinate",
)
UPWARD_AIR_VELOCITY = VarMeta("upward air velocity", "m s-1", "upward_air_velocity")

#: scan dataset (readers of Doppler lidar rays: .hpl, scan NetCDF)
SCAN_VARIABLES: dict[str, VarMeta] = {
    "time": TIME,
    "range": VarMeta("distance from the lidar to the centre of the range gate", "m"),
    "azimuth": VarMeta(
        "azimuth of the beam, clockwise from north", "degree", "sensor_azimuth_angle"
    ),
    "elevation": VarMeta("elevation of the beam above the horizon", "degree"),
    "scan": VarMeta(
        "index of the 360 degree rotation the ray belongs to",
        "1",
        references=SMALIKHO_2020 + ", eqs. 1-2 (one rotation of the conical scan)",
    ),
    "ray": VarMeta("ray index", "1"),
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
}


def _std(of: str, units: str) -> VarMeta:
    """Standard deviation over the averaging interval of the instrument's ``of``."""
    return VarMeta(f"standard deviation of the {of} over the averaging interval", units)


#: wind-record dataset (readers of an instrument's own averages: ZephIR, WindCube)
WIND_RECORD_VARIABLES: dict[str, VarMeta] = {
    "time": TIME,
    "height": HEIGHT,
    "latitude": LATITUDE,
    "longitude": LONGITUDE,
    "wind_speed": VarMeta("horizontal wind speed", "m s-1", "wind_speed"),
    "wind_direction": VarMeta(
        "wind direction (from which the wind blows, clockwise from north)",
        "degree",
        "wind_from_direction",
    ),
    "w": UPWARD_AIR_VELOCITY,
    "wind_speed_std": _std("horizontal wind speed", "m s-1"),
    "wind_speed_min": VarMeta("minimum horizontal wind speed in the averaging interval", "m s-1"),
    "wind_speed_max": VarMeta("maximum horizontal wind speed in the averaging interval", "m s-1"),
    "w_std": _std("upward air velocity", "m s-1"),
    "turbulence_intensity": VarMeta(
        "turbulence intensity as measured (standard deviation over mean of the horizontal "
        "wind speed)",
        "1",
    ),
    "data_availability": VarMeta("proportion of valid measurements in the average", "%"),
    "rain_percent": VarMeta("proportion of packets with rain", "%"),
    "raining": VarMeta("rain detected by the instrument (0 no, 1 yes)", "1"),
    "packets": VarMeta("number of 1-s scan packets in the average", "1"),
    "met_packets": VarMeta("number of 1-s packets of the met station in the average", "1"),
    "record_id": VarMeta("record number of the instrument", "1"),
    "instrument_timestamp": VarMeta("time stamp of the instrument's own clock", "s"),
    "info_flags": VarMeta("information flags of the instrument (text, undocumented)", "1"),
    "status_flags": VarMeta("status flags of the instrument (text, undocumented)", "1"),
    "battery_voltage": VarMeta("battery voltage", "V"),
    "generator_voltage": VarMeta("generator voltage", "V"),
    "pod_upper_temperature": VarMeta("temperature in the upper part of the pod", "degC"),
    "pod_lower_temperature": VarMeta("temperature in the lower part of the pod", "degC"),
    "pod_humidity": VarMeta("relative humidity inside the pod", "%"),
    "internal_temperature": VarMeta("temperature inside the instrument", "degC"),
    "bearing": VarMeta("bearing of the instrument, clockwise from north", "degree"),
    "tilt": VarMeta("tilt of the instrument from the vertical", "degree"),
    "wiper_count": VarMeta("number of wiper runs", "1"),
    "air_temperature": VarMeta("air temperature", "degC", "air_temperature"),
    "air_pressure": VarMeta("air pressure", "hPa", "air_pressure"),
    "relative_humidity": VarMeta("relative humidity", "%", "relative_humidity"),
    "met_wind_speed": VarMeta("wind speed of the met station", "m s-1", "wind_speed"),
    "met_wind_direction": VarMeta(
        "wind direction of the met station (from which the wind blows)",
        "degree",
        "wind_from_direction",
    ),
    "cnr": VarMeta("carrier-to-noise ratio", "dB"),
    "cnr_std": _std("carrier-to-noise ratio", "dB"),
    "cnr_min": VarMeta("minimum carrier-to-noise ratio in the averaging interval", "dB"),
    "cnr_max": VarMeta("maximum carrier-to-noise ratio in the averaging interval", "dB"),
    "spectral_broadening": VarMeta("Doppler spectral broadening", "m s-1"),
    "spectral_broadening_std": _std("Doppler spectral broadening", "m s-1"),
    "u_instrument": VarMeta(
        "horizontal wind component um of the instrument (sign convention not stated)", "m s-1"
    ),
    "u_instrument_std": _std("instrument's component um", "m s-1"),
    "v_instrument": VarMeta(
        "horizontal wind component vm of the instrument (sign convention not stated)", "m s-1"
    ),
    "v_instrument_std": _std("instrument's component vm", "m s-1"),
    # WindCube .rtd lines of sight (cwproc.io.windcube_rtd)
    "radial_velocity": SCAN_VARIABLES["radial_velocity"],
    "radial_velocity_dispersion": VarMeta(
        "dispersion of the radial velocity written by the instrument for one line of sight",
        "m s-1",
    ),
    "beam": VarMeta("line of sight: azimuth of the inclined beam (deg) or V (vertical)", "1"),
    "beam_azimuth": VarMeta("azimuth of the beam, clockwise from north", "degree"),
    "beam_elevation": VarMeta("elevation of the beam above the horizon", "degree"),
    "wiper_on": VarMeta("wiper running during the line of sight (0 no, 1 yes)", "1"),
}

#: sonic dataset (readers of anemometer samples); u, v, w in the instrument frame
SONIC_VARIABLES: dict[str, VarMeta] = {
    "time": TIME,
    "u": VarMeta("wind component along the x axis of the instrument frame", "m s-1"),
    "v": VarMeta("wind component along the y axis of the instrument frame", "m s-1"),
    "w": VarMeta("wind component along the z axis of the instrument frame (up)", "m s-1"),
    "temperature": VarMeta("sonic temperature", "degC", "virtual_temperature"),
    "diagnostic": VarMeta("instrument diagnostic word (0 = good)", "1"),
    "sample_flag": VarMeta(
        "sonic sample flag (bits combine)",
        "1",
        flag_masks=(1, 2, 4),
        flag_meanings="instrument_diagnostic spike missing_or_not_finite",
        comment=(
            "0 good; bit 1 non-zero instrument diagnostic; bit 2 spike; bit 4 missing or not finite"
        ),
    ),
}

#: the table of each canonical dataset
DATASET_VARIABLES: dict[str, dict[str, VarMeta]] = {
    "scan": SCAN_VARIABLES,
    "wind_record": WIND_RECORD_VARIABLES,
    "sonic": SONIC_VARIABLES,
}


def attach_attrs(
    ds: xr.Dataset, table: Mapping[str, VarMeta], *, flag_arrays: bool = True
) -> xr.Dataset:
    """Attach the declared attributes of ``table`` to the variables of ``ds``.

    The declared attributes (:data:`DECLARED_ATTRS`: names, units, flags, citations)
    replace any of those already set; other attributes (what a stage did: ``method``,
    parameters) are kept. Flag masks and values take the dtype of their integer
    variable (as CF requires of a file; ``flag_arrays=False``: plain lists of int, as a
    stage's output holds them, comparable with ``==``); coordinates are ACDD
    ``coordinate`` content. A datetime64 variable keeps no ``units`` (the NetCDF
    encoding sets them).

    Returns
    -------
    xarray.Dataset
        A shallow copy with the attributes set; variables not in ``table`` untouched.
    """
    out = ds.copy()
    coords = set(out.coords)
    for name, var in out.variables.items():  # the copy's own Variable objects
        meta = table.get(str(name))
        if meta is None:
            continue
        attrs = {k: v for k, v in var.attrs.items() if k not in DECLARED_ATTRS}
        attrs.update(meta.attrs())
        for key in ("flag_values", "flag_masks"):
            if flag_arrays and key in attrs and var.dtype.kind in "iu":
                attrs[key] = np.asarray(attrs[key], dtype=var.dtype)
        if var.dtype.kind == "M":
            attrs.pop("units", None)
        if name in coords:
            attrs["coverage_content_type"] = "coordinate"
        var.attrs = attrs
    return out
