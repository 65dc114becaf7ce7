"""cwproc products in the layout of ACTRIS Cloudnet (``[output] layout = "cloudnet"``).

cloudnetpy reads Doppler lidar files by Cloudnet's variable names, which clash with
cwproc's: in Cloudnet ``v`` is the Doppler velocity of a stare and the wind components
are ``uwind``/``vwind``, where cwproc's wind product (``DESIGN.md`` section 2, names
users rely on) has ``u``/``v``. One file cannot serve both, so the Cloudnet layout adds
two translated files beside cwproc's, and cwproc's own products stay unchanged:

* ``<unit>_doppler-lidar.nc`` from the L1 product (``doppler_lidar``): dims ``(time,
  range)``, ``v`` and ``beta`` masked by the screening (``beta_raw`` unmasked),
  ``depolarisation``/``depolarisation_raw``, ``beta_cross``/``beta_cross_raw``,
  ``height(range)`` above mean sea level, ``elevation(time)``, ``wavelength`` and
  ``pulses_per_ray`` -- what ``cloudnetpy.products.epsilon_lidar`` and the categorize
  ``Lidar`` reader take;
* ``<unit>_doppler-lidar-wind.nc`` from the wind product: ``uwind``, ``vwind`` (masked
  where ``qc_flag`` is not 0 and in the near range; ``uwind_raw``/``vwind_raw``
  unmasked) on ``(time, range)``, ``height(range)`` above mean sea level.

Both have the global attributes cloudnetpy copies (``year``, ``month``, ``day``,
``location``, ``source``, ``history``, ``file_uuid``, ``cloudnet_file_type``) and time
in hours since the day's midnight UTC, as Cloudnet files have. Missing values are NaN
with ``_FillValue`` NaN, which netCDF4 reads as masked.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import xarray as xr

#: product names of the Cloudnet layout (their file names end ``_<name>.nc``)
CLOUDNET_L1 = "doppler-lidar"
CLOUDNET_WIND = "doppler-lidar-wind"


def _day(ds: xr.Dataset) -> np.datetime64:
    t = np.asarray(ds["time"].values, dtype="datetime64[ns]")
    t = t[~np.isnat(t)]
    return (t.min() if t.size else np.datetime64("1970-01-01")).astype("datetime64[D]")


def _hours_since_midnight(ds: xr.Dataset) -> xr.Dataset:
    """``time`` encoded as hours since the first time's midnight (Cloudnet's unit)."""
    day = str(_day(ds))
    ds["time"].encoding.update(
        units=f"hours since {day} 00:00:00 +00:00", calendar="standard", dtype="float64"
    )
    return ds


def _cloudnet_globals(ds: xr.Dataset, file_type: str, site: str, source: str) -> dict[str, object]:
    day = str(_day(ds))
    return {
        "cloudnet_file_type": file_type,
        "year": day[:4],
        "month": day[5:7],
        "day": day[8:10],
        "location": site or "unknown",
        "source": source,
    }


def cloudnet_doppler_lidar(
    l1: xr.Dataset, *, altitude_m: float = 0.0, site: str = "", source: str = ""
) -> xr.Dataset:
    """The ``doppler-lidar`` file of Cloudnet from cwproc's L1 product.

    Parameters
    ----------
    l1 : xarray.Dataset
        :func:`cwproc.stages.doppler_lidar.doppler_lidar_product`.
    altitude_m : float
        Instrument altitude above mean sea level (m): ``height = altitude + range sin(el)``.
    site, source : str
        ``location`` and ``source`` global attributes.
    """
    dims = ("time", "range")
    data = {
        "beta": (dims, l1["beta_screened"].values),
        "beta_raw": (dims, l1["beta"].values),
        "v": (dims, l1["radial_velocity_screened"].values),
        "snr": (dims, l1["snr"].values),
        "wavelength": ((), float(l1.attrs.get("lidar_wavelength_m", 1.565e-6))),
    }
    if "depolarisation" in l1:
        data["depolarisation"] = (dims, l1["depolarisation_screened"].values)
        data["depolarisation_raw"] = (dims, l1["depolarisation"].values)
        mask = np.isnan(l1["beta_screened"].values)
        data["beta_cross"] = (dims, np.where(mask, np.nan, l1["beta_cross"].values))
        data["beta_cross_raw"] = (dims, l1["beta_cross"].values)
        data["polariser_bleed_through"] = ((), float(l1.attrs.get("polariser_bleed_through", 0)))
    if l1.attrs.get("pulses_per_ray"):
        data["pulses_per_ray"] = ((), np.uint32(int(l1.attrs["pulses_per_ray"])))
    out = xr.Dataset(
        data,
        coords={
            "time": l1["time"].values,
            "range": l1["range"].values,
            "height": ("range", float(altitude_m) + l1["height"].values),
            "elevation": ("time", l1["elevation"].values),
        },
    )
    out.attrs = {
        **_carried(l1.attrs),
        **_cloudnet_globals(l1, CLOUDNET_L1, site, source),
    }
    return _hours_since_midnight(out)


def cloudnet_wind(
    wind: xr.Dataset,
    *,
    altitude_m: float = 0.0,
    site: str = "",
    source: str = "",
    near_range_m: float = 90.0,
) -> xr.Dataset:
    """The ``doppler-lidar-wind`` file of Cloudnet from cwproc's wind product.

    ``uwind``/``vwind`` are masked (NaN) where the VAD ``qc_flag`` is not 0 and at the
    heights whose range gate is nearer than ``near_range_m`` (the outgoing pulse, three
    pulse lengths: Cloudnet masks them, and so does cwproc's L1 flag bit 1);
    ``uwind_raw``/``vwind_raw`` keep every fitted value.
    """
    good = np.asarray(wind["qc_flag"].values) == 0
    if "range" in wind.coords and wind["range"].dims == ("height",):
        near = np.asarray(wind["range"].values, dtype=float) < near_range_m
        good = good & ~near[None, :]
    u = np.asarray(wind["u"].values, dtype=float)
    v = np.asarray(wind["v"].values, dtype=float)
    # the gates are the dimension (``range``), as in the L1 file: ``height`` above mean
    # sea level is then an auxiliary coordinate, whose CF name is ``altitude``
    dims = ("time", "range")
    height = float(altitude_m) + np.asarray(wind["height"].values, dtype=float)
    coords = {"time": wind["time"].values, "height": ("range", height)}
    if "range" in wind.coords and wind["range"].dims == ("height",):
        coords["range"] = ("range", np.asarray(wind["range"].values, dtype=float))
    out = xr.Dataset(
        {
            "uwind": (dims, np.where(good, u, np.nan)),
            "vwind": (dims, np.where(good, v, np.nan)),
            "uwind_raw": (dims, u),
            "vwind_raw": (dims, v),
        },
        coords=coords,
    )
    out.attrs = {
        **_carried(wind.attrs),
        **_cloudnet_globals(wind, CLOUDNET_WIND, site, source),
    }
    return _hours_since_midnight(out)


def _carried(attrs: Mapping[str, object]) -> dict[str, object]:
    keep = ("system_id", "snr_correction", "background_files", "beta_method", "screening_method")
    return {k: attrs[k] for k in keep if k in attrs}


def cloudnet_products(
    products: Mapping[str, xr.Dataset],
    *,
    altitude_m: float | None,
    site: str,
    source: str,
    near_range_m: float = 90.0,
) -> dict[str, xr.Dataset]:
    """The Cloudnet files of a unit's products (``{}`` when it has neither L1 nor wind)."""
    alt = 0.0 if altitude_m is None else float(altitude_m)
    out: dict[str, xr.Dataset] = {}
    if "doppler_lidar" in products:
        out[CLOUDNET_L1] = cloudnet_doppler_lidar(
            products["doppler_lidar"], altitude_m=alt, site=site, source=source
        )
    if "wind" in products and "u" in products["wind"] and "qc_flag" in products["wind"]:
        out[CLOUDNET_WIND] = cloudnet_wind(
            products["wind"], altitude_m=alt, site=site, source=source, near_range_m=near_range_m
        )
    return out
