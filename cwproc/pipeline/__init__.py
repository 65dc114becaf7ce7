"""Composition of the stages: the only module that knows their order.

``retrieve_files`` is what ``cwproc retrieve`` and ``cwproc batch`` call. It reads
every input on its own (a bad file fails alone, with one line naming the file, the
line and the problem), groups what belongs together into *product units*, runs the
stage chain of each unit and writes the products atomically.

Stage chains
------------
scan data (Stream Line ``.hpl``, cw line-of-sight NetCDF)::

    read -> concat_scans -> qc.screen_radial_velocity -> vad.fit_vad -> wind product
    screened scans + wind -> structure.azimuth_structure_function
                          -> epsilon.estimate_epsilon -> turbulence product

    (a day of scans runs chunk by chunk, :mod:`cwproc.pipeline.stream`, with the products
    of the whole day)
wind records (ZephIR, WindCube)::

    read -> zephir.wind_record_product (qc, TI corrected for volume averaging) -> wind product
sonic data::

    read -> sonic_sf.structure_function_types -> sonic SF product (+ summary tables)
"""

from __future__ import annotations

import dataclasses
import os
import re
import stat
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import xarray as xr

from cwproc.config import Config, InstrumentConfig
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import KIND, FileIdentity, Format, detect_format, get_identifier, get_reader
from cwproc.io.netcdf import discard, publish, remove_stale_temporaries, sha256_file
from cwproc.io.scans import is_homodyne
from cwproc.physics.transfer import CWProbe, Probe, PulsedProbe
from cwproc.products.catalogue import describe_product
from cwproc.products.writer import add_site_coordinates, site_attributes, write_product


@dataclass
class InputFile:
    """One input: its path, format, checksum and (once read) dataset."""

    path: Path
    format: Format
    sha256: str
    dataset: xr.Dataset | None = None
    #: the UTC day this item holds when a file crossing midnight was split (sonic)
    day: str | None = None
    #: time of its first ray (scan files; orders the files of a streamed day)
    start: np.datetime64 | None = None
    #: what the header says (attributes, first time) when the data are not read yet
    identity: FileIdentity | None = None


@dataclass
class ProductUnit:
    """Inputs that make one set of products (e.g. one instrument-day of scans)."""

    key: str
    kind: str
    inputs: list[InputFile] = field(default_factory=list)
    #: one line per input left out when its data were read (damaged beyond its header)
    failures: list[str] = field(default_factory=list)


@dataclass
class RunReport:
    """What a run did: products written and one line per failure."""

    written: list[Path] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    #: the products made, ``(unit key, product name, dataset)``, when asked to keep them
    products: list[tuple[str, str, xr.Dataset]] = field(default_factory=list)
    #: things the user should know that are not failures (e.g. turbulence not computable)
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.failures

    def extend(self, other: RunReport) -> None:
        self.written.extend(other.written)
        self.failures.extend(other.failures)
        self.notes.extend(other.notes)


# --------------------------------------------------------------------------------------
# reading and grouping
# --------------------------------------------------------------------------------------


def reader_options(config: Config, fmt: Format) -> dict:
    """Options of the reader of ``fmt`` from the ``[reader.<format>]`` config table."""
    return dict(config.reader.get(fmt.value, {}))


def read_input(
    path: str | os.PathLike, config: Config, *, identify_only: bool = False
) -> InputFile:
    """Detect the format of one file, checksum it and read it.

    With ``identify_only``, a format with a header-only identifier (``.hpl``) is not
    read: the item gets ``identity`` (attributes and first time, enough for
    :func:`unit_key`) and no dataset, and its data are read when its unit is processed.
    A header the identifier cannot take is read whole (and its error reported).

    Raises
    ------
    InputFileError
        Whatever the reader found wrong with the file.
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        kind = "a folder" if stat.S_ISDIR(mode) else "a pipe, socket or device"
        raise InputFileError(path, f"not a regular file ({kind}); cwproc reads files")
    fmt = (
        detect_format(path)
        if config.instrument.format == "auto"
        else Format(config.instrument.format)
    )
    try:
        checksum = sha256_file(path)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    if fmt is Format.HALO_BACKGROUND:  # read by correct_background for the scans beside it
        return InputFile(path=path, format=fmt, sha256=checksum)
    identify = get_identifier(fmt) if identify_only and not reader_options(config, fmt) else None
    if identify is not None:
        try:
            identity = identify(path)
        except CwprocError:
            identity = None  # read whole below: its reader words the problem
        if identity is not None:
            return InputFile(
                path=path, format=fmt, sha256=checksum, identity=identity, start=_start(identity)
            )
    ds = get_reader(fmt)(path, **reader_options(config, fmt))
    return InputFile(path=path, format=fmt, sha256=checksum, dataset=ds, start=_start(ds))


def held_or_identity(item: InputFile) -> xr.Dataset | FileIdentity | None:
    """The dataset of an input when held, else what its header said (attributes)."""
    return item.dataset if item.dataset is not None else item.identity


def _times(ds: xr.Dataset | FileIdentity) -> np.ndarray:
    """The times of a dataset or of a file's identity (empty when it has none)."""
    if isinstance(ds, FileIdentity):
        return ds.time
    return ds["time"].values if "time" in ds.variables else np.array([], "datetime64[ns]")


def _start(ds: xr.Dataset | FileIdentity) -> np.datetime64 | None:
    """The earliest valid time of a dataset (None when it has none)."""
    t = _times(ds)
    t = t[~np.isnat(t)]
    return t.min() if t.size else None


def _day(ds: xr.Dataset | FileIdentity) -> str:
    t = _times(ds)
    t = t[~np.isnat(t)]
    if t.size == 0:
        return "nodate"
    return np.datetime_as_string(np.min(t), unit="D").replace("-", "")


#: characters kept in a part of a product name; anything else becomes "-"
_NAME_CHARS = re.compile(r"[^A-Za-z0-9._+@-]+")
#: a product file name: no separator, no leading dot, nothing a shell or a filesystem
#: would take for something else
_PLAIN_NAME = re.compile(r"[A-Za-z0-9_+@-][A-Za-z0-9._+@-]*")
#: longest part of a product name taken from a file (characters)
NAME_PART_MAX = 40


def name_part(text: object, default: str = "x") -> str:
    """A safe part of a product file name built from untrusted text (a header value).

    Only letters, digits and ``._+@-`` are kept (other runs become ``-``, leading dots
    and dashes are dropped), and the part is cut to ``NAME_PART_MAX``
    characters: a ``System ID`` of ``../../tmp/pwned``, a NUL or 300 characters can
    neither leave the output folder nor make an invalid file name.
    """
    part = _NAME_CHARS.sub("-", str(text)).lstrip(".-")[:NAME_PART_MAX].rstrip(".-")
    return part or default


def _sonic_station(ds: xr.Dataset) -> str:
    """The logger or instrument identity a sonic file states ('' when none)."""
    for key in ("toa5_station", "tob1_station", "ghg_instrument", "ghg_serial_number"):
        value = str(ds.attrs.get(key, "")).strip()
        if value:
            return value
    return str(ds.attrs.get("meteo2_station", "")).strip()


def unit_key(item: InputFile) -> tuple[str, str]:
    """(kind, key) of the product unit an input belongs to; the key names the products.

    Scan files group by instrument, system id and UTC day; sonic files by format, the
    station the file names (TOA5/TOB1 station, GHG instrument, Meteo-2 ``# station:``;
    else the name of its folder) and UTC day, so two loggers of one day are never
    merged; wind records are one unit each, named after their folder and file, so
    same-named files of two instruments are two units. Every part taken from a file is
    made safe by :func:`name_part`, so the key is a plain file name.
    """
    kind = KIND[item.format]
    ds = held_or_identity(item)
    assert ds is not None
    if kind == "scan":
        system = name_part(ds.attrs.get("system_id", ""))
        instrument = name_part(ds.attrs.get("instrument_kind", item.format.value))
        return kind, f"{instrument}_{system}_{_day(ds)}"
    folder = name_part(Path(item.path).absolute().parent.name, "root")
    if kind == "sonic":
        station = _sonic_station(ds)
        where = name_part(station) if station else folder
        return kind, f"{item.format.value}_{where}_{_day(ds)}"
    return kind, f"{folder}_{name_part(Path(item.path).stem)}"


def split_by_day(item: InputFile) -> list[InputFile]:
    """A sonic input as one item per UTC day of its samples (other inputs unchanged).

    Sonic products are made per day (Gladkikh et al. (2014) type 10-min windows, and a
    15-min logger file holds one and a half of them), so a file that crosses midnight
    contributes to two days.
    """
    ds = item.dataset
    if KIND[item.format] != "sonic" or ds is None or ds.sizes.get("time", 0) == 0:
        return [item]
    days = ds["time"].values.astype("datetime64[D]")
    unique = np.unique(days[~np.isnat(days)])
    if unique.size <= 1:
        return [item]
    return [
        dataclasses.replace(item, dataset=ds.isel(time=np.flatnonzero(days == day)), day=str(day))
        for day in unique
    ]


def group_units(items: Iterable[InputFile]) -> list[ProductUnit]:
    """Group read inputs into product units (scans and sonic data: per instrument and
    UTC day; wind records: per file), in a stable order."""
    units: dict[tuple[str, str], ProductUnit] = {}
    for whole in items:
        for item in split_by_day(whole):
            kind, key = unit_key(item)
            units.setdefault((kind, key), ProductUnit(key=key, kind=kind)).inputs.append(item)
    return [units[k] for k in sorted(units)]


# --------------------------------------------------------------------------------------
# stage chains (pure: Dataset -> Datasets)
# --------------------------------------------------------------------------------------


def probe_from_config(
    instrument: InstrumentConfig, *, pulse_transfer: Literal["physical", "printed"] = "physical"
) -> Probe:
    """The probe of an instrument configuration.

    Parameters
    ----------
    instrument : InstrumentConfig
        ``kind == "pulsed"`` gives a ``PulsedProbe`` from ``delta_p_m`` and ``delta_r_m``;
        ``kind == "cw"`` a ``CWProbe`` from ``beam_radius_m`` and ``wavelength_m`` when
        the beam radius is set, else from ``z_r_coefficient``
        (:mod:`cwproc.physics.transfer`).
    pulse_transfer : {"physical", "printed"}
        Form of the Gaussian term of a pulsed probe (see ``PulsedProbe``).

    Raises
    ------
    ValueError
        For ``kind == "sonic"`` (no probe volume) or an impossible parameter.
    """
    if instrument.kind == "pulsed":
        return PulsedProbe(instrument.delta_p_m, instrument.delta_r_m, pulse_transfer)
    if instrument.kind == "cw":
        if instrument.beam_radius_m is not None:
            return CWProbe(
                instrument.z_r_coefficient, instrument.wavelength_m, instrument.beam_radius_m
            )
        return CWProbe(instrument.z_r_coefficient)
    raise ValueError(f"instrument kind {instrument.kind!r} has no lidar probe volume")


def probe_for(config: Config) -> Probe:
    """The probe-volume description of the configured instrument (physics object).

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
    return probe_from_config(config.instrument, pulse_transfer=config.turbulence.pulse_transfer)


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
    scans: xr.Dataset, config: Config, notes: list[str] | None = None
) -> dict[str, xr.Dataset]:
    """Wind and turbulence products from a scan dataset (already concatenated).

    A wind profile that can be fitted is always returned. When the turbulence chain
    cannot run on these scans (e.g. azimuth steps wider than the 9 degree lag limit of
    Smalikho (2020)), the reason is appended to ``notes`` and only the wind product is
    returned.
    """
    screened, wind = screened_wind(scans, config)
    products = {"wind": wind}
    if not config.turbulence.enabled or int(wind.sizes.get("time", 0)) < 1:
        return products
    mismatch = probe_mismatch(scans, config)
    if mismatch:
        if notes is not None:
            notes.append(f"turbulence not computed: {mismatch}")
        return products
    from cwproc.stages import epsilon, structure

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
            probe=probe_for(config),
            lag_number=config.turbulence.lag_number,
            model=config.turbulence.model,
        )
    elif notes is not None:
        notes.append("turbulence not computed: no complete block of scans")
    return products


# --------------------------------------------------------------------------------------
# one day of mixed scans (issue 13): stares -> stare product, the rest -> wind/turbulence
# --------------------------------------------------------------------------------------


def describe_scan_inputs(unit: ProductUnit) -> list[str]:
    """One line per scan file of a unit: what it holds and which product it feeds."""
    from cwproc.stages.stare import stare_mask

    lines = []
    for item in unit.inputs:
        ds = item.dataset
        if ds is None:
            continue
        vertical = stare_mask(ds)
        n_vertical, n_other = int(vertical.sum()), int((~vertical).sum())
        scan = ds["scan"].values if "scan" in ds.coords else np.full(ds.sizes["ray"], -1)
        n_conical = int(np.unique(scan[(scan >= 0) & ~vertical]).size)
        parts = []
        if n_vertical:
            parts.append(f"{n_vertical} vertical stare rays -> stare product")
        if n_conical:
            parts.append(f"{n_conical} conical scan(s) -> wind (and turbulence)")
        unused = n_other - int(np.sum((scan >= 0) & ~vertical))
        if unused:
            parts.append(f"{unused} rays neither vertical nor in a conical scan: not used")
        kind = str(ds.attrs.get("scan_type", "")).strip() or "scan"
        lines.append(f"{os.fspath(item.path)}: {kind}: " + "; ".join(parts or ["no rays"]))
    return lines


def process_scan_day(
    scans: xr.Dataset, config: Config, notes: list[str] | None = None
) -> dict[str, xr.Dataset]:
    """Products of the scans of one instrument-day: wind/turbulence and stare.

    Vertical stares (elevation >= 85 deg) go to the stare product (w statistics and
    eps of O'Connor et al. (2010), the wind speed from this day's VADs); the other rays
    to :func:`process_scans`. A day of stares only gives the stare product (eps NaN,
    flag bit 1, and a note); a day without stares gives what it gave before.
    """
    from cwproc.stages.stare import split_stares

    stares, others = split_stares(scans)
    products: dict[str, xr.Dataset] = {}
    if others is not None:
        try:
            products = process_scans(others, config, notes)
        except CwprocError as exc:
            if stares is None:
                raise
            if notes is not None:
                notes.append(f"wind not computed: {exc}")
    elif stares is None:
        return process_scans(scans, config, notes)
    if stares is not None and config.stare.enabled:
        products["stare"] = stare_products(stares, products.get("wind"), config, notes)
    return products


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
    )
    product = stare_product(stares, wind if has_wind else None, options)
    ray_s = float(product.attrs["ray_duration_s"])
    if notes is not None and options.variance_window_s < 3 * ray_s:
        notes.append(
            f"stare: [stare] variance_window_s = {options.variance_window_s:g} s holds fewer "
            f"than 3 rays of {ray_s:.2f} s: no variance and no eps (stare_flag bit 2); "
            "lengthen it"
        )
    return product


def process_wind_record(record: xr.Dataset, config: Config) -> dict[str, xr.Dataset]:
    """Wind product from an instrument's own 10-min/1-s wind records (ZephIR, WindCube)."""
    from cwproc.stages import zephir

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


#: relative spread of the sampling rates of sonic files that may be joined into one day
SONIC_RATE_TOLERANCE = 0.01


def concat_sonic(parts: Sequence[xr.Dataset], label: str) -> xr.Dataset:
    """Join the sonic datasets of one instrument-day in time order.

    Raises
    ------
    CwprocError
        The parts have sampling rates that differ by more than 1 %.
    """
    rates = np.array([float(p.attrs["sampling_rate_hz"]) for p in parts])
    if np.ptp(rates) > SONIC_RATE_TOLERANCE * np.median(rates):
        listed = ", ".join(f"{r:g}" for r in rates)
        raise CwprocError(f"{label}: inputs have different sampling rates ({listed} Hz)")
    ds = parts[0] if len(parts) == 1 else xr.concat(parts, dim="time", combine_attrs="drop")
    ds = ds.sortby("time")
    ds.attrs = dict(parts[0].attrs)
    ds.attrs["sampling_rate_hz"] = float(np.median(rates))
    return ds


def concat_unit(unit: ProductUnit) -> xr.Dataset:
    """The datasets of a unit as one (scans and sonic days: joined in time order)."""
    datasets = [i.dataset for i in unit.inputs if i.dataset is not None]
    if unit.kind == "scan":
        from cwproc.io.scans import concat_scans

        return concat_scans(datasets)
    if unit.kind == "sonic":
        return concat_sonic(datasets, unit.key)
    if len(datasets) != 1:
        raise CwprocError(f"unit {unit.key}: expected one input, got {len(datasets)}")
    return datasets[0]


def process_unit(
    unit: ProductUnit,
    config: Config,
    notes: list[str] | None = None,
    *,
    chunk_bytes: int | None = None,
) -> dict[str, xr.Dataset]:
    """Run the stage chain of one unit; returns ``{product_name: dataset}``.

    Non-fatal remarks (a product that could not be made) are appended to ``notes``.
    A scan unit is processed chunk by chunk (:func:`cwproc.pipeline.stream.stream_scan_unit`,
    identical products in bounded memory); a day whose chunks would choose differently
    from the whole day is processed whole.
    """
    if unit.kind == "scan":
        from cwproc.pipeline.stream import STREAM_CHUNK_BYTES, stream_scan_unit

        products = stream_scan_unit(
            unit,
            config,
            notes,
            lambda item: load_item(item, config),
            chunk_bytes or STREAM_CHUNK_BYTES,
        )
        if products is not None:
            return products
    load_unit(unit, config)
    ds = concat_unit(unit)
    if unit.kind == "scan":
        if notes is not None:
            notes.extend(describe_scan_inputs(unit))
        ds = correct_background(ds, unit, config, notes)
        return process_scan_day(ds, config, notes)
    if unit.kind == "wind_record":
        return process_wind_record(ds, config)
    return process_sonic(ds, config)


def correct_background(
    scans: xr.Dataset, unit: ProductUnit, config: Config, notes: list[str] | None = None
) -> xr.Dataset:
    """Stream Line scans with the SNR corrected by the background files (stage ``background``).

    Background files (``*Background_*.txt``) are looked for in ``[background] folder``,
    else beside each ``.hpl`` file of the unit; each ray takes the latest one measured
    at most ``max_age_h`` before it (Manninen et al. (2016); Vakkari et al. (2019)).
    Other scans, a switched-off correction or no background file: ``scans`` unchanged.
    A damaged background file is named in ``notes`` and the others are used.
    """
    opts = config.background
    if not opts.enabled or "snr" not in scans:
        return scans
    if str(scans.attrs.get("instrument_kind", "")).lower() != "streamline":
        return scans
    from cwproc.stages import background

    files = background.find_background_files((i.path for i in unit.inputs), opts.folder or None)
    if not files:
        if opts.folder and notes is not None:  # a configured folder: say why nothing is used
            notes.append(background.missing_folder_note(opts.folder))
        return scans
    return background.correct_snr(
        scans,
        background.read_backgrounds(
            files, notes, ray_time=scans["time"].values, max_age_h=opts.max_age_h
        ),
        max_age_h=opts.max_age_h,
        min_range_m=opts.min_range_m,
        notes=notes,
    )


# --------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------


def product_path(outdir: str | os.PathLike, unit: ProductUnit, name: str) -> Path:
    """``OUTDIR/<unit key>_<product>.nc``.

    Raises
    ------
    CwprocError
        The name is not a plain file name (a key not made by :func:`unit_key`).
    """
    filename = f"{unit.key}_{name}.nc"
    if not _PLAIN_NAME.fullmatch(filename) or len(filename) > 200:
        raise CwprocError(f"product name {filename!r} is not a plain file name")
    return Path(outdir) / filename


def write_unit_products(
    unit: ProductUnit, products: dict[str, xr.Dataset], outdir: str | os.PathLike, config: Config
) -> list[Path]:
    """Write the products of one unit with provenance, all or none; returns the paths.

    Every product is first written completely to a hidden temporary; only when all of
    them are written are they renamed onto their names (:func:`cwproc.io.netcdf.publish`),
    so a full disk or a kill never leaves half a unit (wind without turbulence).
    """
    staged: list[tuple[Path, Path]] = []
    try:
        return _write_staged(unit, products, outdir, config, staged)
    except BaseException:
        discard(staged)
        raise


def _write_staged(
    unit: ProductUnit,
    products: dict[str, xr.Dataset],
    outdir: str | os.PathLike,
    config: Config,
    staged: list[tuple[Path, Path]],
) -> list[Path]:
    """Stage every product of ``unit`` (appending to ``staged``), then publish them."""
    instrument_attrs = site_attributes(config.output)
    first = held_or_identity(unit.inputs[0]) if unit.inputs else None
    if first is not None and first.attrs.get("instrument"):
        instrument_attrs["instrument"] = str(first.attrs["instrument"])
    for name, ds in products.items():
        about = describe_product(name, unit.kind)
        path = product_path(outdir, unit, name)
        staged.append(
            (
                write_product(
                    add_site_coordinates(ds, config.output),
                    path,
                    title=f"cwproc {about.title}: {unit.key}",
                    summary=about.summary,
                    inputs=list(dict.fromkeys(i.path for i in unit.inputs)),
                    checksums={os.fspath(i.path): i.sha256 for i in unit.inputs},
                    config_toml=config.to_toml(),
                    references=about.references,
                    keywords=about.keywords,
                    extra_attrs=instrument_attrs,
                    compression_level=config.output.compression_level,
                    stage_only=True,
                ),
                path,
            )
        )
    return publish(staged)


def retrieve_files(
    paths: Sequence[str | os.PathLike],
    outdir: str | os.PathLike,
    config: Config,
    *,
    kinds: Iterable[str] | None = None,
    keep_products: bool = False,
) -> RunReport:
    """Read, process and write everything; never stops at the first bad input.

    Parameters
    ----------
    paths : sequence of paths
        Input files.
    outdir : path
        Directory of the products.
    config : Config
    kinds : iterable of str, optional
        Accept only inputs of these kinds (``"scan"``, ``"wind_record"``, ``"sonic"``);
        others are reported as failures. Default: all.
    keep_products : bool
        Keep the product datasets in the report (``report.products``).

    Returns
    -------
    RunReport
        Products written and one line per failed input or unit.
    """
    report = RunReport()
    for stale in remove_stale_temporaries(outdir):
        report.notes.append(f"{stale}: removed a temporary file of an interrupted run")
    units: dict[tuple[str, str], ProductUnit] = {}
    accepted = set(kinds) if kinds is not None else None
    held = 0
    for p in paths:
        try:
            item = read_input(p, config, identify_only=True)
        except CwprocError as exc:
            report.failures.append(str(exc))
            continue
        except Exception as exc:  # a reader bug must not stop the other files
            report.failures.append(f"{p}: {internal_error(exc)}")
            continue
        if KIND[item.format] == "background":  # not a product input (see correct_background)
            report.notes.append(f"{p}: Stream Line background file, not a product input")
            continue
        if accepted is not None and KIND[item.format] not in accepted:
            report.failures.append(
                f"{p}: {item.format.value} data ({KIND[item.format]}) cannot be used here; "
                f"expected {' or '.join(sorted(accepted))} data"
            )
            continue
        for part in split_by_day(item):
            kind, key = unit_key(part)
            units.setdefault((kind, key), ProductUnit(key=key, kind=kind)).inputs.append(part)
            held += _nbytes(part.dataset)
            if held > RETRIEVE_MEMORY_BYTES:  # keep only what the budget allows
                held -= _nbytes(part.dataset)
                part.dataset = None
    for unit_id in sorted(units):
        unit = units.pop(unit_id)
        names = unit_label(unit)
        notes: list[str] = []
        try:
            products = process_unit(unit, config, notes)
            report.written.extend(write_unit_products(unit, products, outdir, config))
            if keep_products:
                report.products.extend((unit.key, n, ds) for n, ds in products.items())
        except CwprocError as exc:
            report.failures.append(f"{names}: {exc}")
        except Exception as exc:  # a bug in cwproc: report it, keep processing the rest
            report.failures.append(f"{names}: {internal_error(exc)}")
        finally:
            report.failures.extend(unit.failures)
            for item in unit.inputs:  # processed: its data may go
                item.dataset = None
        own = tuple(f"{os.fspath(i.path)}: " for i in unit.inputs)
        report.notes.extend(n if n.startswith(own) else f"{names}: {n}" for n in notes)
    return report


#: input data ``retrieve`` keeps in memory between reading and processing (bytes);
#: beyond it, inputs are read again when their unit is processed, so memory stays flat
#: in the number of units (a unit's own data plus this budget)
RETRIEVE_MEMORY_BYTES = 512 << 20


def _nbytes(ds: xr.Dataset | None) -> int:
    return 0 if ds is None else int(ds.nbytes)


def load_unit(unit: ProductUnit, config: Config) -> None:
    """Read again the inputs of ``unit`` whose data were not kept (memory budget).

    Raises
    ------
    CwprocError
        An input changed or vanished since it was first read (its checksum differs).
    """
    for item in list(unit.inputs):
        if item.dataset is None:
            try:
                item.dataset = load_item(item, config)
            except InputFileError as exc:  # identified by its header, damaged beyond it
                drop_input(unit, item, exc)


def drop_input(unit: ProductUnit, item: InputFile, exc: InputFileError) -> None:
    """Leave out of ``unit`` an input whose data cannot be read; its line in ``failures``."""
    unit.inputs.remove(item)
    unit.failures.append(str(exc))


def load_item(item: InputFile, config: Config) -> xr.Dataset | None:
    """The dataset of ``item``: the one held, else the file read again (not stored).

    Raises
    ------
    CwprocError
        The input changed or vanished since it was first read (its checksum differs).
    """
    if item.dataset is not None:
        return item.dataset
    again = read_input(item.path, config)
    if again.sha256 != item.sha256:
        raise CwprocError(f"{item.path}: changed while cwproc was running; run again")
    ds = again.dataset
    if item.day is not None and ds is not None:
        days = ds["time"].values.astype("datetime64[D]")
        ds = ds.isel(time=np.flatnonzero(days == np.datetime64(item.day, "D")))
    return ds


def internal_error(exc: BaseException) -> str:
    """One line for an unexpected exception: where it came from, to report as a bug."""
    import traceback

    frame = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    where = f" at {Path(frame.filename).name}:{frame.lineno}" if frame else ""
    return (
        f"internal error {type(exc).__name__}{where}: {exc} "
        "(a bug in cwproc; please report it with this line)"
    )


def unit_label(unit: ProductUnit) -> str:
    """The input files of a unit, for messages (the first three and a count)."""
    paths = list(dict.fromkeys(os.fspath(i.path) for i in unit.inputs))
    if len(paths) <= 3:
        return ", ".join(paths)
    return ", ".join(paths[:3]) + f" (+{len(paths) - 3} more)"


def replace_config(config: Config, **sections) -> Config:
    """A copy of ``config`` with whole sections replaced (helper for callers and tests)."""
    return dataclasses.replace(config, **sections)


def unit_inputs(units: Iterable[ProductUnit]) -> dict[str, list[str]]:
    """``{unit key: [input paths]}`` (for reports and the batch ledger)."""
    out: dict[str, list[str]] = defaultdict(list)
    for u in units:
        out[u.key].extend(os.fspath(i.path) for i in u.inputs)
    return dict(out)
