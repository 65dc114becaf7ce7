"""The wind product of instrument wind records (ZephIR, WindCube), and the TP of cw scans.

Configured by the ``[zephir]`` section (also for WindCube).

``wind_record_product`` turns a wind-record dataset (ZephIR Waltz CSV, WindCube
``.sta``; see :mod:`cwproc.io.zephir`, :mod:`cwproc.io.windcube`) into the wind
product: speed, direction, ``w``, ``u``/``v`` from speed and direction, the measured
turbulence intensity and, for conically scanning cw lidars, the turbulence intensity
corrected for volume averaging, i.e. divided by the ratio sigma_lidar / sigma_cup that
the model of Wagner et al. (DTU) predicts at that height and wind speed
(:mod:`cwproc.physics.volume_averaging`).

``turbulence_parameter`` computes the ZephIR turbulence parameter TP of Wagner et al.
(DTU), eq. 8, from the wind product of the ``vad`` stage: the standard deviation of
the radial-velocity residuals about the fitted cosine over one rotation, divided by
the mean horizontal wind speed.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.metadata import described
from cwproc.physics.constants import ZEPHIR_Z_R_COEFFICIENT
from cwproc.physics.geometry import wind_components
from cwproc.physics.volume_averaging import std_ratio_and_tp_share

#: qc_flag bits of the wind-record product (they combine; 0 = good)
FLAG_TOO_FEW_PACKETS = 1
FLAG_MISSING = 4
FLAG_RAIN = 8

#: wind speeds (m s-1) at which the volume-averaging ratio is tabulated per height
_RATIO_WIND_GRID = np.geomspace(0.5, 40.0, 40)
#: ZephIR 300 scan time behind one wind value (s). Evidence: the 10-min export of unit
#: 317 holds 31-36 packets per height and 10 min while cycling 11 heights, i.e. at most
#: 600 / (11 x 35) = 1.6 s per packet: one 1-s rotation each (Wagner et al. (DTU),
#: sect. 2.2: 1-s or 3-s scans).
DEFAULT_SCAN_TIME_S = 1.0
#: Wagner et al. (DTU), sect. 4.1: 10-min periods with >= 65 % of the possible samples
DEFAULT_MIN_AVAILABILITY_PERCENT = 65.0


def predicted_std_ratio(
    height: np.ndarray,
    wind_speed: np.ndarray,
    *,
    scan_time_s: float = DEFAULT_SCAN_TIME_S,
    z_r_coefficient: float = ZEPHIR_Z_R_COEFFICIENT,
    window_s: float = 600.0,
) -> np.ndarray:
    """sigma_lidar / sigma_cup of Wagner et al. (DTU), eqs. 9-11, for many (h, U) pairs.

    The ratio is tabulated once per distinct height on a grid of wind speeds
    (0.5-40 m s-1, log-spaced) and interpolated in ``ln U``; outside the grid the
    nearest end value is used.

    Parameters
    ----------
    height : ndarray
        Height above the lidar (m), broadcast against ``wind_speed``.
    wind_speed : ndarray
        Mean horizontal wind speed (m s-1).
    scan_time_s : float
        Scan duration behind one wind value (s).
    z_r_coefficient : float
        ``c`` of ``Z_R = c R²`` (1/m).
    window_s : float
        Averaging window of the statistics (s).

    Returns
    -------
    ndarray
        Ratio (1); NaN where the height is not positive or the speed not finite.
    """
    h, u = np.broadcast_arrays(np.asarray(height, float), np.asarray(wind_speed, float))
    out = np.full(h.shape, np.nan)
    for hi in np.unique(h[np.isfinite(h) & (h > 0)]):
        table = np.array(
            [
                std_ratio_and_tp_share(
                    hi, ui, scan_time_s, z_r_coefficient=z_r_coefficient, window_s=window_s
                )[0]
                for ui in _RATIO_WIND_GRID
            ]
        )
        sel = (h == hi) & np.isfinite(u)
        speeds = np.clip(u[sel], _RATIO_WIND_GRID[0], _RATIO_WIND_GRID[-1])
        out[sel] = np.interp(np.log(speeds), np.log(_RATIO_WIND_GRID), table)
    return out


def _missing_like(like: xr.DataArray) -> xr.DataArray:
    """All-NaN values on the dims and coordinates of ``like``, without its attributes."""
    return xr.DataArray(np.full(like.shape, np.nan), dims=like.dims, coords=like.coords)


def _measured_ti(record: xr.Dataset) -> xr.DataArray:
    if "turbulence_intensity" in record:
        return record["turbulence_intensity"]
    if "wind_speed_std" in record:
        return record["wind_speed_std"] / record["wind_speed"].where(record["wind_speed"] > 0)
    return _missing_like(record["wind_speed"])


def _flags(
    record: xr.Dataset, *, min_packets: int, max_rain_percent: float, min_availability: float
) -> xr.DataArray:
    flag = xr.zeros_like(record["wind_speed"], dtype=np.int8)
    long_average = float(record.attrs.get("averaging_interval_s", 600.0)) >= 60.0
    if "packets" in record and long_average:
        flag = flag | xr.where(record["packets"].fillna(0) < min_packets, FLAG_TOO_FEW_PACKETS, 0)
    if "data_availability" in record:
        low = record["data_availability"].fillna(0) < min_availability
        flag = flag | xr.where(low, FLAG_TOO_FEW_PACKETS, 0)
    missing = ~np.isfinite(record["wind_speed"]) | ~np.isfinite(record["wind_direction"])
    if "w" in record and bool(np.isfinite(record["w"]).any()):  # a w column is exported
        missing = missing | ~np.isfinite(record["w"])
    flag = flag | xr.where(missing, FLAG_MISSING, 0)
    if "rain_percent" in record:
        flag = flag | xr.where(record["rain_percent"] > max_rain_percent, FLAG_RAIN, 0)
    if "raining" in record:
        flag = flag | xr.where(record["raining"] > 0, FLAG_RAIN, 0)
    return flag.astype(np.int8)


@described("wind_record")
def wind_record_product(
    record: xr.Dataset,
    *,
    min_packets: int = 24,
    max_rain_percent: float = 50.0,
    z_r_coefficient: float = ZEPHIR_Z_R_COEFFICIENT,
    scan_time_s: float | None = None,
    min_availability_percent: float = DEFAULT_MIN_AVAILABILITY_PERCENT,
) -> xr.Dataset:
    """Wind product from an instrument's own wind records (ZephIR, WindCube).

    Parameters
    ----------
    record : xarray.Dataset
        Wind-record dataset, dims ``(time, height)`` with at least ``wind_speed`` and
        ``wind_direction`` (m s-1, deg "from").
    min_packets : int
        Fewest scan packets in an average of 1 min or longer (ZephIR ``packets``);
        fewer sets qc bit 1. Not applied to 1-s records (one packet each).
    max_rain_percent : float
        Largest proportion of packets with rain (%); more sets qc bit 8 (1-s files:
        ``raining`` = 1 sets it).
    z_r_coefficient : float
        ``c`` of ``Z_R = c R²`` (1/m) for the probe filter, Wagner et al. (DTU), eq. 2.
    scan_time_s : float, optional
        Scan duration behind one wind value (s); default ``record.attrs["scan_time_s"]``
        or 1 s (ZephIR 300, see :data:`DEFAULT_SCAN_TIME_S`).
    min_availability_percent : float
        Lowest data availability (%) of WindCube records; less sets qc bit 1
        (Wagner et al. (DTU), sect. 4.1: 65 %).

    Returns
    -------
    xarray.Dataset
        dims ``(time, height)``: ``wind_speed``, ``wind_direction``, ``w``, ``u``, ``v``,
        ``wind_speed_std``, ``turbulence_intensity`` (measured),
        ``volume_averaging_ratio`` (predicted sigma_lidar/sigma_cup) and
        ``turbulence_intensity_corrected`` (cw lidars; NaN for other instruments),
        ``n_packets`` or ``data_availability``, ``qc_flag`` (bit 1 too few
        packets/availability, bit 4 missing value, bit 8 rain); flagged values are kept.

    Raises
    ------
    CwprocError
        The record has no ``wind_speed``/``wind_direction`` or no records.
    """
    for name in ("wind_speed", "wind_direction"):
        if name not in record:
            raise CwprocError(f"wind record has no {name!r}: not a wind-record dataset")
    if record.sizes.get("time", 0) == 0 or record.sizes.get("height", 0) == 0:
        raise CwprocError("wind record is empty (no times or no heights)")
    out = _exported_wind(record)
    ti = _measured_ti(record)
    out["turbulence_intensity"] = ti
    out["turbulence_intensity"].attrs["method"] = (
        "exported by the instrument"
        if "turbulence_intensity" in record
        else "wind_speed_std / wind_speed"
    )
    scan_time = float(
        scan_time_s
        if scan_time_s is not None
        else record.attrs.get("scan_time_s", DEFAULT_SCAN_TIME_S)
    )
    ratio, note = _volume_averaging_ratio(
        record, scan_time_s=scan_time, z_r_coefficient=z_r_coefficient
    )
    out["volume_averaging_ratio"] = ratio
    out["volume_averaging_ratio"].attrs["method"] = note
    if "turbulence_intensity_corrected" in record:  # DBS statistics of .rtd beams
        out["turbulence_intensity_corrected"] = record["turbulence_intensity_corrected"]
        for name in ("turbulence_intensity", "turbulence_intensity_corrected"):
            out[name].attrs["method"] = record[name].attrs.get("method", "")
        for c in "uvw":
            if f"{c}_variance" in record:
                out[f"{c}_variance_dbs"] = record[f"{c}_variance"]
        if "dbs_flag" in record:
            out["dbs_flag"] = record["dbs_flag"]
    else:
        out["turbulence_intensity_corrected"] = ti / out["volume_averaging_ratio"]
        out["turbulence_intensity_corrected"].attrs["method"] = (
            "turbulence_intensity / volume_averaging_ratio; " + note
        )
    out["qc_flag"] = _flags(
        record,
        min_packets=min_packets,
        max_rain_percent=max_rain_percent,
        min_availability=min_availability_percent,
    )
    out["qc_flag"].attrs["method"] = (
        f"wind records: bit 1 packets < {min_packets} (averages >= 1 min) or availability "
        f"< {min_availability_percent:g} %; bit 4 missing value (instrument code, NaN or "
        "physically impossible; w too where the record exports it); "
        f"bit 8 rain > {max_rain_percent:g} % of packets"
    )
    out.attrs = {k: record.attrs[k] for k in _KEPT_ATTRS if k in record.attrs}
    out.attrs["scan_time_s"] = scan_time
    return out


#: dataset attributes of the wind record that the product keeps
_KEPT_ATTRS = (
    "instrument",
    "instrument_kind",
    "system_id",
    "averaging_interval_s",
    "time_stamp_position",
    "utc_offset_applied_h",
    "reference_height_m",
    "window_height_m",
    "scan_angle_deg",
    "dbs_references",
    "dbs_flag_meanings",
)


def _exported_wind(record: xr.Dataset) -> xr.Dataset:
    """Speed, direction, w, u and v (from speed and direction) and the exported statistics."""
    speed = record["wind_speed"]
    out = xr.Dataset(coords={"time": record["time"], "height": record["height"]})
    out["wind_speed"] = speed
    out["wind_direction"] = record["wind_direction"]
    u, v = wind_components(speed.values, record["wind_direction"].values)
    out["u"] = (speed.dims, u)
    out["v"] = (speed.dims, v)
    out["w"] = record["w"] if "w" in record else _missing_like(speed)
    for name in ("wind_speed_std", "wind_speed_min", "wind_speed_max", "data_availability"):
        if name in record:
            out[name] = record[name]
    if "packets" in record:
        out["n_packets"] = record["packets"]
    for name in ("rain_percent", "raining"):
        if name in record:
            out[name] = record[name]
    for var in ("u", "v"):
        out[var].attrs["method"] = "from the exported speed and direction (from)"
    return out


def _volume_averaging_ratio(
    record: xr.Dataset, *, scan_time_s: float, z_r_coefficient: float
) -> tuple[xr.DataArray, str]:
    """Predicted sigma_lidar / sigma_cup of the record (Wagner et al. (DTU), eqs. 9-11).

    Returns
    -------
    ratio : xarray.DataArray
        The ratio (1) on the dims of ``wind_speed``; NaN for instruments other than
        conically scanning cw lidars and for statistics shorter than 1 min.
    note : str
        How it was computed (or why not).
    """
    speed = record["wind_speed"]
    window = float(record.attrs.get("averaging_interval_s", 600.0))
    if record.attrs.get("instrument_kind") != "cw" or window < 60.0:
        note = (
            "not applicable: the model is for conically scanning cw lidars with "
            "statistics over >= 1 min"
        )
        return _missing_like(speed), note
    above_lidar = record["height"] - float(record.attrs.get("window_height_m", 0.0))
    h2d, u2d = xr.broadcast(above_lidar, speed)
    ratio = predicted_std_ratio(
        h2d.transpose(*speed.dims).values,
        u2d.transpose(*speed.dims).values,
        scan_time_s=scan_time_s,
        z_r_coefficient=z_r_coefficient,
        window_s=window,
    )
    note = (
        f"Kaimal spectrum, Lorentzian probe Z_R = {z_r_coefficient:g} R^2, "
        f"R = h/cos30 (h above the lidar window), {scan_time_s:g}-s conical scan, "
        f"{window:g}-s statistics"
    )
    return xr.DataArray(ratio, dims=speed.dims, coords=speed.coords), note


def turbulence_parameter(wind: xr.Dataset) -> xr.DataArray:
    """ZephIR turbulence parameter TP per rotation, Wagner et al. (DTU), eq. 8.

    .. math:: TP = \\frac{\\sqrt{\\langle (V_r - \\hat V_r(\\theta))^2 \\rangle}}{U}

    the standard deviation of the radial-velocity residuals about the cosine fitted
    over one rotation, divided by the mean horizontal wind speed; ``(TP U)²`` carries
    the turbulence between the probe length and ``l_az`` (eqs. 12-13).

    Parameters
    ----------
    wind : xarray.Dataset
        Wind product of :func:`cwproc.stages.vad.fit_vad` (``residual_std``, m s-1, and
        ``wind_speed``, m s-1).

    Returns
    -------
    xarray.DataArray
        ``turbulence_parameter`` (1), NaN where the wind speed is not positive.
    """
    for name in ("residual_std", "wind_speed"):
        if name not in wind:
            raise CwprocError(f"wind product has no {name!r}: TP needs the vad stage output")
    speed = wind["wind_speed"]
    tp = wind["residual_std"] / speed.where(speed > 0)
    tp.name = "turbulence_parameter"
    tp.attrs = {"method": "residual_std / wind_speed per rotation"}
    return tp
