"""The stage chain of scan data, :class:`ScanChain`: the one place that names it.

Stream Line ``.hpl`` and cw line-of-sight NetCDF scans, each step with its reach::

    chunk  -> background.correct_snr (per ray, ScanChain.prepare)
           -> stare.split_stares (per ray, ScanChain.split)
    others -> qc.screen_radial_velocity -> vad.fit_vad (per scan, ScanChain.fit)
           -> wind product
    screened scans + wind -> structure.azimuth_structure_function
                             (per block of N scans, ScanChain.blocks)
    the day's blocks -> epsilon.estimate_epsilon -> turbulence product
    vertical stares -> stare.stare_product (+ the day's VAD wind) -> stare product
                       (and doppler_lidar.doppler_lidar_product: L1)
                       (per day, ScanChain.finish)

:class:`ScanChain` also holds the day's decisions (:meth:`ScanChain.decisions`: scan
numbering, the VAD's conical elevation, the azimuth step and rotation);
:func:`cwproc.pipeline.stream.run_scan_chain` runs it over one chunk (the whole day) or
many (a day in bounded memory), with the same products. The configuration is unpacked
here into the plain arguments of the stages.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from cwproc import memory
from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.pipeline.background_files import SnrCorrection, snr_corrected_scans
from cwproc.pipeline.probe import probe_attrs, probe_for, probe_mismatch, pulse_rate_hz
from cwproc.pipeline.product_units import ProductUnit

if TYPE_CHECKING:
    from cwproc.stages.doppler_lidar import DopplerLidarOptions

__all__ = [
    "Carry",
    "DayDecisions",
    "DayParts",
    "Fitted",
    "PartsDiffer",
    "Pointing",
    "Rows",
    "ScanChain",
    "count_stare_rays",
    "describe_scan_file",
    "describe_scan_inputs",
    "doppler_lidar_options",
    "doppler_lidar_products",
    "stare_products",
    "vertical_rays",
]

# The stages are imported by the functions that run them: a command imports the chain
# of its own kind of data only (the lidar chain's scipy.integrate, optimize and special
# took 0.55 s of each sf-type run, a quarter of its time).


@dataclass(frozen=True)
class Fitted:
    """Screened conical scans and their VAD wind rows (:meth:`ScanChain.fit`)."""

    screened: xr.Dataset
    wind: xr.Dataset


@dataclass(frozen=True)
class Carry:
    """Screened rays and wind rows of the scans of an incomplete block, carried into the
    next chunk (:meth:`ScanChain.blocks`)."""

    screened: xr.Dataset
    wind: xr.Dataset


@dataclass(frozen=True)
class Pointing:
    """Per-ray time, azimuth and elevation (deg) of a day, and its files' scan type."""

    time: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    scan_type: str


@dataclass(frozen=True)
class DayDecisions:
    """What the whole day decides, which every chunk of a streamed day must repeat.

    Attributes
    ----------
    scan : numpy.ndarray
        Scan index of each ray (:func:`cwproc.io.scan_join.scan_indices` over the day).
    vad_elevation_deg : float or None
        The conical elevation the VAD keeps (the day's most common); None: no wind.
    vad_scans_other_elevation : int
        Conical scans left out for another elevation.
    wind_scans : numpy.ndarray
        The scans the VAD fits, in order.
    azimuth_step : (float, float) or None
        Azimuth step (deg) and rotation (+1 clockwise) of the wind scans' rays (None:
        no structure function).
    """

    scan: np.ndarray
    vad_elevation_deg: float | None = None
    vad_scans_other_elevation: int = 0
    wind_scans: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    azimuth_step: tuple[float, float] | None = None

    def differences(self, other: DayDecisions) -> str:
        """What ``other`` decided differently ('' when nothing)."""
        if not np.array_equal(self.scan, other.scan):
            return "scan numbering"
        vad = (self.vad_elevation_deg, self.vad_scans_other_elevation)
        if vad != (other.vad_elevation_deg, other.vad_scans_other_elevation):
            return "conical elevation"
        if not np.array_equal(self.wind_scans, other.wind_scans):
            return "conical scans of the day"
        if self.azimuth_step != other.azimuth_step:
            return "azimuth step"
        return ""


@dataclass
class DayParts:
    """The pieces a day's products are made of (one each for a day run whole).

    ``attrs``: the attributes of the day's scans; ``joined``: the pieces come from
    several chunks, so the products take the day's attributes, not a chunk's.
    """

    attrs: dict
    winds: Rows = field(default_factory=lambda: Rows("time"))
    sfs: Rows = field(default_factory=lambda: Rows("time"))
    stares: Rows = field(default_factory=lambda: Rows("ray"))
    turbulence: bool = True
    joined: bool = False


class PartsDiffer(CwprocError):
    """Parts of a day that cannot be one dataset (other variables, gates or lags)."""


class Rows:
    """Datasets of the same variables along one dimension, kept as numpy arrays and
    joined once (:meth:`joined`).

    The parts of a day (its chunks' wind rows, blocks of structure statistics, stare
    rays) hold the same variables; those along ``dim`` are kept as arrays and the others
    (coordinates such as ``height``, ``lag``), the attributes, encodings and the order
    of the variables are the first part's: the result of ``xr.concat(parts, dim,
    combine_attrs="override")`` in one ``numpy.concatenate`` per variable (xarray's
    join aligns and compares the parts variable by variable: 0.1-0.2 s for the 24 parts
    of a day of 480 scans).
    """

    def __init__(self, dim: str) -> None:
        self.dim = dim
        self.first: xr.Dataset | None = None
        self.arrays: dict[str, list[np.ndarray]] = {}
        self.size = 0

    def __bool__(self) -> bool:
        return self.first is not None

    def append(self, part: xr.Dataset) -> None:
        """Keep ``part``'s values along ``dim``.

        Raises
        ------
        PartsDiffer
            ``part`` has other variables than the first part, or another value of a
            variable not along ``dim``.
        """
        if self.first is None:
            self.first = part
            self.arrays = {n: [v.values] for n, v in part.variables.items() if self.dim in v.dims}
        else:
            first = self.first.variables
            if part.variables.keys() != first.keys():
                raise PartsDiffer(f"parts along {self.dim} with other variables")
            for name, var in first.items():
                other = part.variables[name]
                if name in self.arrays and other.dims == var.dims and other.dtype == var.dtype:
                    self.arrays[name].append(other.values)
                elif name in self.arrays or not _same_values(other, var):
                    raise PartsDiffer(f"parts along {self.dim} with another {name}")
        self.size += int(part.sizes.get(self.dim, 0))

    def joined(self) -> xr.Dataset:
        """The parts as one dataset (the first part itself when it is the only one)."""
        first = self.first
        if first is None:
            raise ValueError("no part to join")
        if all(len(values) == 1 for values in self.arrays.values()):
            return first
        variables = {}
        for name, var in first.variables.items():
            if name in self.arrays:
                data = np.concatenate(self.arrays[name], axis=var.dims.index(self.dim))
                var = xr.Variable(var.dims, data, var.attrs, var.encoding)
            variables[name] = var
        return xr.Dataset(
            {name: variables[name] for name in first.data_vars},
            coords={name: variables[name] for name in first.coords},
            attrs=dict(first.attrs),
        )

    @staticmethod
    def of(parts: Sequence[xr.Dataset], dim: str) -> xr.Dataset:
        """``parts`` joined along ``dim``."""
        rows = Rows(dim)
        for part in parts:
            rows.append(part)
        return rows.joined()


def _same_values(a: xr.Variable, b: xr.Variable) -> bool:
    """``a.equals(b)`` (dimensions and values, NaN equal to NaN) without xarray's
    per-call overhead (about 1 ms)."""
    if a is b:
        return True
    if a.dims != b.dims or a.shape != b.shape:
        return False
    x, y = a.values, b.values
    nan = x.dtype.kind in "fc" and y.dtype.kind in "fc"
    return bool(np.array_equal(x, y, equal_nan=nan))


@dataclass(frozen=True)
class ScanChain:
    """The stage chain of scan data, and the decisions the whole day makes.

    Built from a :class:`~cwproc.config.Config`; each method is one step of the chain
    with its reach (ray, scan, block of ``[turbulence] n_scans`` scans, day). Run by
    :func:`cwproc.pipeline.stream.run_scan_chain` over one chunk or many.
    """

    config: Config

    def prepare(
        self,
        chunk: xr.Dataset,
        unit: ProductUnit,
        files: list[Path] | None,
        notes: list[str] | None,
    ) -> tuple[xr.Dataset, SnrCorrection]:
        """Per ray: the SNR corrected with the background files of ``unit``.

        ``files``: :func:`~cwproc.pipeline.background_files.find_background_files` of the
        unit when the caller holds them (a streamed day looks once, not once per
        chunk). The summary line is the record's (:class:`SnrCorrection`): the caller
        writes one for the day.
        """
        return snr_corrected_scans(chunk, unit, self.config, notes, files=files)

    def split(self, ds: xr.Dataset) -> tuple[xr.Dataset | None, xr.Dataset | None]:
        """Per ray: ``(stares, others)``, the vertical stares and the other rays."""
        from cwproc.stages.stare import split_stares, stare_mask

        vertical = stare_mask(ds)
        # without stares the dataset is taken as it is (split_stares would copy it)
        return split_stares(ds) if vertical.any() else (None, ds)

    def fit(self, others: xr.Dataset) -> Fitted:
        """Per scan: the rays screened (stage ``qc``) and the VAD wind (stage ``vad``)."""
        from cwproc.io.scan_join import is_homodyne
        from cwproc.stages import qc, vad

        c = self.config
        homodyne = is_homodyne(others)
        screened = qc.screen_radial_velocity(
            others,
            snr_min=c.qc.snr_min,
            outlier_threshold=c.qc.outlier_threshold,
            homodyne=homodyne,
        )
        wind = vad.fit_vad(
            screened,
            min_rays=c.vad.min_rays,
            max_gap_deg=c.vad.max_gap_deg,
            reference_direction_deg=c.vad.reference_direction_deg,
            max_residual_std=c.vad.max_residual_std,
            homodyne=homodyne,
        )
        return Fitted(screened, wind)

    def blocks(
        self, carry: Carry | None, fitted: Fitted | None, *, final: bool
    ) -> tuple[xr.Dataset | None, Carry | None]:
        """Per block: the structure function of the complete blocks of N scans.

        Blocks are ``[turbulence] n_scans`` consecutive wind rows from the first of the
        day (Smalikho (2020), eq. 1), as
        :func:`cwproc.stages.structure.azimuth_structure_function` forms them on the
        whole day: the carried scans first, then ``fitted``; the scans of an incomplete
        last block are carried (``final``: the short last block is reduced too).

        Returns
        -------
        (sf or None, carry or None)
        """
        from cwproc.stages import structure

        parts = [p for p in (carry, fitted) if p is not None]
        if not parts:
            return None, None
        screened = Rows.of([p.screened for p in parts], "ray")
        wind = Rows.of([p.wind for p in parts], "time")
        n_scans = self.config.turbulence.n_scans
        n = int(wind.sizes["time"])
        k = n if final else n // n_scans * n_scans
        rest = None
        if k < n:
            kept = np.isin(screened["scan"].values, wind["scan"].values[k:])
            rest = Carry(screened.isel(ray=np.flatnonzero(kept)), wind.isel(time=slice(k, None)))
        if k == 0:
            return None, rest
        sf = structure.azimuth_structure_function(
            screened,
            wind.isel(time=slice(0, k)) if k < n else wind,
            n_scans=n_scans,
            max_lag_deg=self.config.turbulence.max_lag_deg,
            min_lags=self.config.turbulence.min_lags,
        )
        return sf, rest

    def decisions(self, pointing: Pointing, *, wind: bool, step: bool) -> DayDecisions:
        """What the whole day decides, from its pointing alone (24 bytes a ray).

        The scan numbering (:func:`cwproc.io.scan_join.scan_indices`); with ``wind``, the
        VAD's conical scans (:func:`cwproc.physics.scan_layout.select_conical_scans`); with
        ``step``, the azimuth step and rotation of their rays
        (:func:`cwproc.physics.scan_layout.azimuth_step`).
        """
        from cwproc.io.scan_join import scan_indices
        from cwproc.physics import scan_layout

        time, az, el = pointing.time, pointing.azimuth, pointing.elevation
        scan, _ = scan_indices(time, az, el, scan_type=pointing.scan_type)
        if not wind:
            return DayDecisions(scan)
        layout, phi, _, n_other = scan_layout.select_conical_scans(
            scan_layout.scan_layout(scan, np.isfinite(az) & np.isfinite(el)), el
        )
        rays = np.isin(scan, layout.scan_ids)
        found = scan_layout.azimuth_step(az[rays], scan[rays]) if step else None
        return DayDecisions(scan, phi, n_other, layout.scan_ids, found)

    def turbulence_note(self, scans: xr.Dataset) -> str:
        """Why no turbulence product is made of these scans ('' when one is)."""
        mismatch = probe_mismatch(scans, self.config)
        return f"turbulence not computed: {mismatch}" if mismatch else ""

    def finish(
        self,
        day: DayParts,
        notes: list[str] | None,
        cross: xr.Dataset | None = None,
    ) -> dict[str, xr.Dataset]:
        """Per day: the wind, turbulence (eps with the probe), stare and L1 products.

        The parts of ``day`` are released as they are joined: the chunks' pieces are
        not held by the dissipation-rate fit, whose working arrays make the day's peak.
        """
        from cwproc.stages import epsilon
        from cwproc.stages.structure import INSTRUMENT_SETTINGS

        c, attrs = self.config, day.attrs
        products: dict[str, xr.Dataset] = {}
        rows = day.winds.size
        if day.winds:
            wind = day.winds.joined()
            day.winds = Rows("time")
            if day.joined:
                vad_attrs = {k: v for k, v in wind.attrs.items() if k.startswith("vad_")}
                wind.attrs = {**attrs, **vad_attrs}
            products["wind"] = wind
        if day.sfs:
            sf = day.sfs.joined()
            day.sfs = Rows("time")
            if day.joined:
                sf.attrs["instrument"] = str(attrs.get("instrument", ""))
                for key in INSTRUMENT_SETTINGS:  # the day's, as the whole-day run has them
                    sf.attrs.pop(key, None)
                    if key in attrs:
                        sf.attrs[key] = attrs[key]
            with memory.phase("day_fit"):
                turbulence = epsilon.estimate_epsilon(
                    sf,
                    probe=probe_for(c, attrs),
                    lag_number=c.turbulence.lag_number,
                    model=c.turbulence.model,
                    prf_hz=pulse_rate_hz(c, attrs),
                )
            turbulence.attrs.update(probe_attrs(c, attrs))
            products["turbulence"] = turbulence
        elif day.turbulence and rows and notes is not None:
            notes.append("turbulence not computed: no complete block of scans")
        if day.stares and (c.stare.enabled or c.doppler_lidar.enabled):
            stares = day.stares.joined()
            day.stares = Rows("ray")
            if day.joined:
                stares.attrs = dict(attrs)
            if c.stare.enabled:
                products["stare"] = stare_products(stares, products.get("wind"), c, notes)
            if c.doppler_lidar.enabled:
                products["doppler_lidar"] = doppler_lidar_products(stares, cross, c, notes)
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


def vertical_rays(scans: xr.Dataset) -> np.ndarray:
    """Per ray, True for a vertical stare (the rays :meth:`ScanChain.split` sets apart)."""
    from cwproc.stages.stare import stare_mask

    return stare_mask(scans)


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
