"""The stage chains of each kind of unit (pure: datasets in, product datasets out).

scan data (Stream Line ``.hpl``, cw line-of-sight NetCDF): the steps, their reach and
the day's decisions are drawn once, in :mod:`cwproc.pipeline.scan_chain`;
:class:`~cwproc.pipeline.scan_chain.ScanChain` is the only place that names them and
:func:`cwproc.pipeline.stream.run_scan_chain` runs it over one chunk (the whole day:
:func:`process_scan_day`) or many (a day in bounded memory), with the same products.

wind records (ZephIR, WindCube)::

    wind_records.wind_record_product (qc, TI corrected for volume averaging) -> wind product

sonic data::

    sonic_sf.structure_function_types -> sonic SF product (+ summary tables)

The configuration is unpacked here into the plain arguments of the stages.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import pandas as pd
import xarray as xr

from cwproc.config import Config
from cwproc.pipeline.scan_chain import ScanChain

__all__ = [
    "process_scan_day",
    "process_scans",
    "process_sonic",
    "process_wind_record",
    "screened_wind",
    "sf_summary_tables",
]

# The stages are imported by the functions that run them: a command imports the chain
# of its own kind of data only (the lidar chain's scipy.integrate, optimize and special
# took 0.55 s of each sf-type run, a quarter of its time).


def screened_wind(scans: xr.Dataset, config: Config) -> tuple[xr.Dataset, xr.Dataset]:
    """Screened conical scans and their VAD wind rows (:meth:`ScanChain.fit`)."""
    fitted = ScanChain(config).fit(scans)
    return fitted.screened, fitted.wind


def process_scans(
    scans: xr.Dataset,
    config: Config,
    notes: list[str] | None = None,
    kept: dict[str, xr.Dataset] | None = None,
) -> dict[str, xr.Dataset]:
    """Wind and turbulence products from a scan dataset (already concatenated).

    :class:`ScanChain` run whole (:func:`cwproc.pipeline.stream.run_scan_chain`)
    without splitting vertical stares off. A wind profile that can be fitted is always
    returned. When the turbulence chain cannot run on these scans (e.g. azimuth steps
    wider than the 9 degree lag limit of Smalikho (2020)), the reason is appended to
    ``notes`` and only the wind product is returned. ``kept``, when given, receives the
    QC-screened scans the VAD was fitted to (``kept["screened"]``).
    """
    from cwproc.pipeline.stream import run_scan_chain

    return run_scan_chain(
        ScanChain(config), [scans], whole=True, notes=notes, kept=kept, stares=False
    )


def process_scan_day(
    scans: xr.Dataset,
    config: Config,
    notes: list[str] | None = None,
    kept: dict[str, xr.Dataset] | None = None,
    cross: xr.Dataset | None = None,
) -> dict[str, xr.Dataset]:
    """Products of the scans of one instrument-day: wind/turbulence and stare.

    :class:`ScanChain` run whole (:func:`cwproc.pipeline.stream.run_scan_chain`).
    Vertical stares (elevation >= 85 deg) go to the stare product (w statistics and
    eps of O'Connor et al. (2010), the wind speed from this day's VADs); the other rays
    to the wind and turbulence products (``kept`` receives their screened scans). A day
    of stares only gives the stare product (eps NaN, flag bit 1, and a note); with
    ``[doppler_lidar] enabled`` the stares also give the L1 product ``doppler_lidar``
    (beta, and the depolarisation ratio with the ``cross``-polarised stare rays of the
    day when given).
    """
    from cwproc.pipeline.stream import run_scan_chain

    return run_scan_chain(
        ScanChain(config), [scans], whole=True, notes=notes, kept=kept, cross=cross
    )


def process_wind_record(record: xr.Dataset, config: Config) -> dict[str, xr.Dataset]:
    """Wind product from an instrument's own 10-min/1-s wind records (ZephIR, WindCube).

    The lines of sight of a WindCube ``.rtd`` file are first turned into interval
    statistics by DBS (:func:`cwproc.stages.dbs.dbs_statistics`, ``[dbs]``): mean wind
    and turbulence intensity measured and corrected.
    """
    from cwproc.stages import wind_records

    if record.attrs.get("format") == "windcube_rtd":
        from cwproc.stages.dbs import dbs_statistics

        record = dbs_statistics(record, **dataclasses.asdict(config.dbs))

    return {
        "wind": wind_records.wind_record_product(
            record,
            min_packets=config.zephir.min_packets,
            max_rain_percent=config.zephir.max_rain_percent,
            z_r_coefficient=config.instrument.z_r_coefficient,
        )
    }


def process_sonic(sonic: xr.Dataset, config: Config) -> dict[str, xr.Dataset]:
    """Structure-function-type product of a sonic dataset."""
    from cwproc.stages import sonic_sf

    return {"sf": sonic_sf.structure_function_types(sonic, **dataclasses.asdict(config.sonic))}


#: variables of the sonic SF product that the summary tables use
SF_SUMMARY_VARIABLES = (
    "sf_type",
    "window_flag",
    "r_max",
    "sf_mu",
    "sf_a1",
    "sf_a2",
    "sf_d1",
    "sf_d2",
    "sf_gamma",
)


def sf_summary_tables(products: Sequence[xr.Dataset]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Table 2 and Tables 3-5 of Gladkikh et al. (2014) over sonic SF products.

    Parameters
    ----------
    products : sequence of xarray.Dataset
        ``sf`` products (:func:`process_sonic`), joined along ``window``.

    Returns
    -------
    occurrence : pandas.DataFrame
        Occurrence of each structure-function type per component (% of observed
        windows), Gladkikh et al. (2014), Table 2.
    statistics : pandas.DataFrame
        Means and medians of the fitted parameters per type and component,
        Gladkikh et al. (2014), Tables 3-5.
    """
    from cwproc.stages import sonic_sf_tables

    joined = xr.concat([p[list(SF_SUMMARY_VARIABLES)] for p in products], dim="window")
    return sonic_sf_tables.type_occurrence(joined), sonic_sf_tables.parameter_statistics(joined)
