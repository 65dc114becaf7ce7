"""The stage chains of each kind of unit (pure: datasets in, product datasets out).

scan data (Stream Line ``.hpl``, cw line-of-sight NetCDF)::

    qc.screen_radial_velocity -> vad.fit_vad -> wind product
    screened scans + wind -> structure.azimuth_structure_function
                          -> epsilon.estimate_epsilon -> turbulence product
    vertical stares -> stare.stare_product (+ the day's VAD wind) -> stare product

wind records (ZephIR, WindCube)::

    zephir.wind_record_product (qc, TI corrected for volume averaging) -> wind product

sonic data::

    sonic_sf.structure_function_types -> sonic SF product (+ summary tables)

The configuration is unpacked here into the plain arguments of the stages.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Literal

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.config import Config, InstrumentConfig
from cwproc.errors import CwprocError
from cwproc.physics.probe_lengths import ProbeLengths, pulse_rate, pulsed_probe_lengths
from cwproc.pipeline.units import ProductUnit

if TYPE_CHECKING:
    from cwproc.physics.transfer import Probe
    from cwproc.stages.doppler_lidar import DopplerLidarOptions

# The stages are imported by the functions that run them: a command imports the chain
# of its own kind of data only (the lidar chain's scipy.integrate, optimize and special
# took 0.55 s of each sf-type run, a quarter of its time).


def probe_from_config(
    instrument: InstrumentConfig,
    *,
    pulse_transfer: Literal["physical", "printed"] = "physical",
    data_attrs: Mapping[str, object] | None = None,
) -> Probe:
    """The probe of an instrument configuration and of the data it describes.

    Parameters
    ----------
    instrument : InstrumentConfig
        ``kind == "pulsed"`` gives a ``PulsedProbe`` whose ``Delta_R`` is
        ``delta_r_m`` when set, else the data's range gate length (``gate_length_m``,
        the Stream Line header's ``Range gate length (m)``; 18 m when the data have
        none), and whose ``Delta_p`` is ``delta_p_m`` when set, else the instrument
        model's (Stream Line 15.3 m), Smalikho (2020), eq. 19
        (:func:`cwproc.physics.probe_lengths.pulsed_probe_lengths`);
        ``kind == "cw"`` a ``CWProbe`` from ``beam_radius_m`` and ``wavelength_m`` when
        the beam radius is set, else from ``z_r_coefficient``
        (:mod:`cwproc.physics.transfer`).
    pulse_transfer : {"physical", "printed"}
        Form of the Gaussian term of a pulsed probe (see ``PulsedProbe``).
    data_attrs : mapping, optional
        Attributes of the scan dataset (``gate_length_m``, ``instrument_kind``).

    Raises
    ------
    ValueError
        For ``kind == "sonic"`` (no probe volume) or an impossible parameter.
    """
    from cwproc.physics.transfer import CWProbe, PulsedProbe

    if instrument.kind == "pulsed":
        lengths = pulsed_lengths(instrument, data_attrs)
        return PulsedProbe(lengths.delta_p_m, lengths.delta_r_m, pulse_transfer)
    if instrument.kind == "cw":
        if instrument.beam_radius_m is not None:
            return CWProbe(
                instrument.z_r_coefficient, instrument.wavelength_m, instrument.beam_radius_m
            )
        return CWProbe(instrument.z_r_coefficient)
    raise ValueError(f"instrument kind {instrument.kind!r} has no lidar probe volume")


def pulsed_lengths(
    instrument: InstrumentConfig, data_attrs: Mapping[str, object] | None = None
) -> ProbeLengths:
    """``Delta_p``, ``Delta_R`` (m) and their sources for data with ``data_attrs``."""
    return pulsed_probe_lengths(data_attrs or {}, instrument.delta_p_m, instrument.delta_r_m)


def probe_attrs(config: Config, data_attrs: Mapping[str, object] | None) -> dict[str, object]:
    """Product attributes recording the pulsed probe used (empty for a cw lidar).

    The lengths (:func:`pulsed_lengths`) and the pulse repetition frequency
    (:func:`pulse_rate_hz`) with their sources.
    """
    if config.instrument.kind != "pulsed":
        return {}
    rate = pulse_rate(data_attrs or {}, config.instrument.prf_hz)
    return {**pulsed_lengths(config.instrument, data_attrs).attrs(), **rate.attrs()}


def pulse_rate_hz(config: Config, data_attrs: Mapping[str, object] | None) -> float | None:
    """The PRF (Hz) of a pulsed lidar's data: ``[instrument] prf_hz``, else the model's.

    :func:`cwproc.physics.probe_lengths.pulse_rate`; None for other instruments (their
    rays have no pulses to count).
    """
    if config.instrument.kind != "pulsed":
        return None
    return pulse_rate(data_attrs or {}, config.instrument.prf_hz).prf_hz


def probe_for(config: Config, data_attrs: Mapping[str, object] | None = None) -> Probe:
    """The probe-volume description of the configured instrument (physics object).

    ``data_attrs``: the scan dataset's attributes, which give a pulsed probe its range
    gate length (:func:`probe_from_config`).

    Raises
    ------
    CwprocError
        The configuration describes no lidar (``instrument.kind = "sonic"``).
    """
    if config.instrument.kind not in ("pulsed", "cw"):
        raise CwprocError(
            f"configuration {config.source}: instrument.kind = {config.instrument.kind!r} "
            "describes no lidar probe volume; use a lidar configuration (e.g. -c streamline "
            "or -c zephir300) for scan data"
        )
    return probe_from_config(
        config.instrument, pulse_transfer=config.turbulence.pulse_transfer, data_attrs=data_attrs
    )


def probe_mismatch(scans: xr.Dataset, config: Config) -> str:
    """Why the configured probe cannot describe these scans ('' when it can).

    The A-functions and the variance correction depend on the probe volume (pulsed range
    gate or focused cw Lorentzian, Smalikho (2020), eqs. 19-20; Banakh et al. (1999),
    eq. 3); scans whose ``instrument_kind`` differs from ``[instrument] kind`` would get
    an eps of the wrong instrument (a cw series read with the pulsed default config came
    out 3-25 times too low), so no turbulence product is made for them.
    """
    declared = str(scans.attrs.get("instrument_kind", "")).strip().lower()
    kind = {"streamline": "pulsed", "pulsed": "pulsed", "cw": "cw"}.get(declared)
    if kind is None or kind == config.instrument.kind:
        return ""
    files = ", ".join(str(f) for f in np.atleast_1d(scans.attrs.get("source_files", []))[:3])
    return (
        f"the scans{' of ' + files if files else ''} come from a {kind} lidar "
        f"(instrument_kind = {declared!r}) but configuration {config.source} describes a "
        f"{config.instrument.kind} lidar; use a {kind} configuration "
        f"(e.g. -c {'banakh1999' if kind == 'cw' else 'streamline'})"
    )


def screened_wind(scans: xr.Dataset, config: Config) -> tuple[xr.Dataset, xr.Dataset]:
    """Screened conical scans and their VAD wind rows (stages ``qc`` and ``vad``)."""
    from cwproc.io.scans import is_homodyne
    from cwproc.stages import qc, vad

    homodyne = is_homodyne(scans)
    screened = qc.screen_radial_velocity(
        scans,
        snr_min=config.qc.snr_min,
        outlier_threshold=config.qc.outlier_threshold,
        homodyne=homodyne,
    )
    wind = vad.fit_vad(
        screened,
        min_rays=config.vad.min_rays,
        max_gap_deg=config.vad.max_gap_deg,
        reference_direction_deg=config.vad.reference_direction_deg,
        max_residual_std=config.vad.max_residual_std,
        homodyne=homodyne,
    )
    return screened, wind


def process_scans(
    scans: xr.Dataset,
    config: Config,
    notes: list[str] | None = None,
    kept: dict[str, xr.Dataset] | None = None,
) -> dict[str, xr.Dataset]:
    """Wind and turbulence products from a scan dataset (already concatenated).

    A wind profile that can be fitted is always returned. When the turbulence chain
    cannot run on these scans (e.g. azimuth steps wider than the 9 degree lag limit of
    Smalikho (2020)), the reason is appended to ``notes`` and only the wind product is
    returned. ``kept``, when given, receives the QC-screened scans the VAD was fitted
    to (``kept["screened"]``).
    """
    from cwproc.stages import epsilon, structure

    screened, wind = screened_wind(scans, config)
    if kept is not None:
        kept["screened"] = screened
    products = {"wind": wind}
    if not config.turbulence.enabled or int(wind.sizes.get("time", 0)) < 1:
        return products
    mismatch = probe_mismatch(scans, config)
    if mismatch:
        if notes is not None:
            notes.append(f"turbulence not computed: {mismatch}")
        return products
    try:
        sf = structure.azimuth_structure_function(
            screened,
            wind,
            n_scans=config.turbulence.n_scans,
            max_lag_deg=config.turbulence.max_lag_deg,
            min_lags=config.turbulence.min_lags,
        )
    except CwprocError as exc:
        if notes is not None:
            notes.append(f"turbulence not computed: {exc}")
        return products
    if int(sf.sizes.get("time", 0)) >= 1:
        products["turbulence"] = epsilon.estimate_epsilon(
            sf,
            probe=probe_for(config, scans.attrs),
            lag_number=config.turbulence.lag_number,
            model=config.turbulence.model,
            prf_hz=pulse_rate_hz(config, scans.attrs),
        )
        products["turbulence"].attrs.update(probe_attrs(config, scans.attrs))
    elif notes is not None:
        notes.append("turbulence not computed: no complete block of scans")
    return products


# --------------------------------------------------------------------------------------
# one day of mixed scans (issue 13): stares -> stare product, the rest -> wind/turbulence
# --------------------------------------------------------------------------------------


def count_stare_rays(scans: xr.Dataset) -> int:
    """Number of vertical stare rays (elevation >= 85 deg) of a scan dataset.

    The rays :func:`process_scan_day` gives to the stare product (O'Connor et al.
    (2010)); 0 for a dataset without elevations.
    """
    from cwproc.stages.stare import stare_mask

    return int(stare_mask(scans).sum()) if "elevation" in scans else 0


def describe_scan_inputs(unit: ProductUnit) -> list[str]:
    """One line per scan file of a unit: what it holds and which product it feeds."""
    from cwproc.stages.stare import stare_mask

    lines = []
    for item in unit.inputs:
        ds = item.dataset
        if ds is None:
            continue
        scan = ds["scan"].values if "scan" in ds.coords else np.full(ds.sizes["ray"], -1)
        lines.append(describe_scan_file(item.path, ds.attrs, stare_mask(ds), scan))
    return lines


def describe_scan_file(
    path: str | os.PathLike, attrs: dict, vertical: np.ndarray, scan: np.ndarray
) -> str:
    """The line of :func:`describe_scan_inputs` for one file, from its attributes, which
    of its rays are vertical stares and its scan index per ray (numbered in the file)."""
    n_vertical, n_other = int(vertical.sum()), int((~vertical).sum())
    n_conical = int(np.unique(scan[(scan >= 0) & ~vertical]).size)
    parts = []
    if n_vertical:
        parts.append(f"{n_vertical} vertical stare rays -> stare product")
    if n_conical:
        parts.append(f"{n_conical} conical scan(s) -> wind (and turbulence)")
    unused = n_other - int(np.sum((scan >= 0) & ~vertical))
    if unused:
        parts.append(f"{unused} rays neither vertical nor in a conical scan: not used")
    kind = str(attrs.get("scan_type", "")).strip() or "scan"
    return f"{os.fspath(path)}: {kind}: " + "; ".join(parts or ["no rays"])


def process_scan_day(
    scans: xr.Dataset,
    config: Config,
    notes: list[str] | None = None,
    kept: dict[str, xr.Dataset] | None = None,
    cross: xr.Dataset | None = None,
) -> dict[str, xr.Dataset]:
    """Products of the scans of one instrument-day: wind/turbulence and stare.

    Vertical stares (elevation >= 85 deg) go to the stare product (w statistics and
    eps of O'Connor et al. (2010), the wind speed from this day's VADs); the other rays
    to :func:`process_scans` (which fills ``kept``). A day of stares only gives the
    stare product (eps NaN, flag bit 1, and a note); a day without stares gives what it
    gave before. With ``[doppler_lidar] enabled`` the stares also give the L1 product
    ``doppler_lidar`` (beta, and the depolarisation ratio with the ``cross``-polarised
    stare rays of the day when given).
    """
    from cwproc.stages.stare import split_stares

    stares, others = split_stares(scans)
    products: dict[str, xr.Dataset] = {}
    if others is not None:
        try:
            products = process_scans(others, config, notes, kept)
        except CwprocError as exc:
            if stares is None:
                raise
            if notes is not None:
                notes.append(f"wind not computed: {exc}")
    elif stares is None:
        return process_scans(scans, config, notes, kept)
    if stares is not None and config.stare.enabled:
        products["stare"] = stare_products(stares, products.get("wind"), config, notes)
    if stares is not None and config.doppler_lidar.enabled:
        products["doppler_lidar"] = doppler_lidar_products(stares, cross, config, notes)
    return products


def doppler_lidar_options(config: Config) -> DopplerLidarOptions:
    """The options of the L1 stage from the ``[doppler_lidar]`` and ``[stare]`` sections."""
    from cwproc.physics.backscatter import LidarConstants
    from cwproc.stages.doppler_lidar import DopplerLidarOptions

    c = config.doppler_lidar
    return DopplerLidarOptions(
        constants=LidarConstants(
            wavelength_m=c.wavelength_m,
            receiver_bandwidth_hz=c.receiver_bandwidth_hz,
            pulse_energy_j=c.pulse_energy_j,
            effective_diameter_m=c.effective_diameter_m,
            quantum_efficiency=c.quantum_efficiency,
        ),
        near_range_m=c.near_range_m,
        box_rays=c.box_rays,
        box_gates=c.box_gates,
        snr_sigma=c.snr_sigma,
        texture_max_m_s=c.texture_max_m_s,
        bleed_through=c.bleed_through,
        prf_hz=config.stare.prf_hz,
    )


def doppler_lidar_products(
    stares: xr.Dataset, cross: xr.Dataset | None, config: Config, notes: list[str] | None
) -> xr.Dataset:
    """The L1 product of the vertical stares (and of their cross-polarised rays)."""
    from cwproc.stages.doppler_lidar import doppler_lidar_product
    from cwproc.stages.stare import split_stares

    cross_stares = split_stares(cross)[0] if cross is not None else None
    if cross is not None and cross_stares is None and notes is not None:
        notes.append("depolarisation not computed: the cross-polarised files hold no stare rays")
    return doppler_lidar_product(stares, cross_stares, doppler_lidar_options(config), notes)


def stare_products(
    stares: xr.Dataset, wind: xr.Dataset | None, config: Config, notes: list[str] | None
) -> xr.Dataset:
    """The stare product of the vertical rays, with a note when no VAD gives the wind."""
    from cwproc.stages.stare import StareOptions, stare_product

    has_wind = wind is not None and bool(np.isfinite(wind["wind_speed"].values).any())
    if not has_wind and notes is not None:
        notes.append(
            "stare eps not computed: no VAD or PPI of this instrument and day gives the "
            "horizontal wind that O'Connor et al. (2010) need; w statistics written, "
            "epsilon_stare NaN with stare_flag bit 1 (add the day's VAD files)"
        )
    options = StareOptions(
        window_s=config.stare.window_s,
        min_samples=config.stare.min_samples,
        variance_window_s=config.stare.variance_window_s,
        snr_min=config.qc.snr_min,
        outlier_threshold=config.stare.outlier_threshold,
        prf_hz=config.stare.prf_hz,
        max_wind_gap_s=config.stare.max_wind_gap_s,
        delta_p_m=config.instrument.delta_p_m,
        delta_r_m=config.instrument.delta_r_m,
        min_rays_per_variance_window=config.stare.min_rays_per_variance_window,
    )
    product = stare_product(stares, wind if has_wind else None, options)
    used = float(product.attrs["variance_window_s"])
    if notes is not None and used != options.variance_window_s:
        notes.append(
            f"stare: variance windows of {used:.3g} s instead of [stare] variance_window_s = "
            f"{options.variance_window_s:g} s, to hold at least "
            f"{options.min_rays_per_variance_window} rays (a ray every "
            f"{float(product.attrs['ray_interval_s']):.3g} s) in a whole number per "
            f"{options.window_s:g}-s window"
        )
    return product


def process_wind_record(record: xr.Dataset, config: Config) -> dict[str, xr.Dataset]:
    """Wind product from an instrument's own 10-min/1-s wind records (ZephIR, WindCube).

    The lines of sight of a WindCube ``.rtd`` file are first turned into interval
    statistics by DBS (:func:`cwproc.stages.dbs.dbs_statistics`, ``[dbs]``): mean wind
    and turbulence intensity measured and corrected.
    """
    from cwproc.stages import zephir

    if record.attrs.get("format") == "windcube_rtd":
        from cwproc.stages.dbs import dbs_statistics

        record = dbs_statistics(record, **dataclasses.asdict(config.dbs))

    return {
        "wind": zephir.wind_record_product(
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
    from cwproc.stages import sonic_sf

    joined = xr.concat([p[list(SF_SUMMARY_VARIABLES)] for p in products], dim="window")
    return sonic_sf.type_occurrence(joined), sonic_sf.parameter_statistics(joined)
