"""``retrieve_files``: read, run and write every unit of a list of files (``cwproc retrieve``)."""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import xarray as xr

from cwproc import progress
from cwproc.config import Config, default_preset, load_config
from cwproc.errors import CwprocError
from cwproc.io import KIND, NETCDF_LOCK, Format, detect_format
from cwproc.io.netcdf import remove_stale_temporaries
from cwproc.pipeline.input_checks import instrument_mismatch
from cwproc.pipeline.input_files import Examined, InputFile, identify_input, read_input
from cwproc.pipeline.product_units import (
    ProductUnit,
    UnitPart,
    split_by_day,
    unit_label,
    unit_part,
    units_of,
)
from cwproc.pipeline.run import internal_error, run_unit
from cwproc.pipeline.write import IN_MEMORY, product_path, write_unit_products


@dataclass
class RunReport:
    """What a run did: products written and one line per failure."""

    written: list[Path] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    #: the products made, ``(unit key, product name, dataset)``, when asked to keep them
    products: list[tuple[str, str, xr.Dataset]] = field(default_factory=list)
    #: things the user should know that are not failures (e.g. turbulence not computable)
    notes: list[str] = field(default_factory=list)
    #: products of ``written`` that replaced a file of the same name (an earlier run's)
    replaced: list[Path] = field(default_factory=list)
    #: quality reports written beside the products (``[output] qc_report``)
    quality_reports: list[Path] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.failures

    def extend(self, other: RunReport) -> None:
        self.written.extend(other.written)
        self.failures.extend(other.failures)
        self.notes.extend(other.notes)
        self.replaced.extend(other.replaced)
        self.quality_reports.extend(other.quality_reports)


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
        Products written (``replaced``: those that replaced a file of the same name) and
        one line per failed input or unit.

    Notes
    -----
    Reading reports its progress per file and processing per unit
    (:mod:`cwproc.progress`: a bar on the terminal when the command line turned it on).
    """
    report = RunReport()
    for stale in remove_stale_temporaries(outdir):
        report.notes.append(f"{stale}: removed a temporary file of an interrupted run")
    found = read_units(paths, config, kinds=kinds)
    report.failures.extend(found.failures)
    report.notes.extend(found.notes)
    for unit in progress.track(found.units, desc="processing", unit="unit"):
        result = run_unit(unit, config)
        try:
            if result.products:
                existing = [product_path(outdir, unit, n).exists() for n in result.products]
                written = write_unit_products(unit, result.products, outdir, config)
                report.written.extend(written)
                report.replaced.extend(p for p, old in zip(written, existing, strict=True) if old)
                if config.output.qc_report:
                    from cwproc.pipeline.quality import write_quality_reports

                    refused = [*found_failures_of(found.failures, unit), *result.failures]
                    report.quality_reports.extend(
                        write_quality_reports(written, refused, result.notes)
                    )
        except CwprocError as exc:
            report.failures.append(f"{unit_label(unit)}: {exc}")
        except Exception as exc:  # a bug in cwproc: report it, keep processing the rest
            report.failures.append(f"{unit_label(unit)}: {internal_error(exc)}")
        if keep_products:
            report.products.extend((unit.key, n, ds) for n, ds in result.products.items())
        report.failures.extend(result.failures)
        report.notes.extend(result.notes)
        for item in unit.inputs:  # processed: its data may go
            item.dataset = None
    return report


def found_failures_of(failures: Sequence[str], unit: ProductUnit) -> list[str]:
    """The read failures of the run that name a folder of ``unit``'s inputs (the files
    refused there: unreadable, of another instrument), for its quality reports."""
    folders = {os.fspath(Path(i.path).parent) for i in unit.inputs}
    return [f for f in failures if any(f.startswith(d + os.sep) for d in folders)]


#: input data ``retrieve`` keeps in memory between reading and processing (bytes);
#: beyond it, inputs are read again when their unit is processed, so memory stays flat
#: in the number of units (a unit's own data plus this budget)
RETRIEVE_MEMORY_BYTES = 512 << 20


def _nbytes(ds: xr.Dataset | None) -> int:
    return 0 if ds is None else int(ds.nbytes)


class FoundUnits(NamedTuple):
    """The product units of a list of files, and what reading them gave."""

    #: the units in a stable order (sorted by kind and key)
    units: list[ProductUnit]
    #: one line per input that cannot be read or used (file, line, problem)
    failures: list[str]
    #: inputs left out that are not failures (e.g. Stream Line background files)
    notes: list[str]


def read_units(
    paths: Iterable[str | os.PathLike],
    config: Config,
    *,
    kinds: Iterable[str] | None = None,
) -> FoundUnits:
    """Read every input on its own and group the inputs into product units.

    What ``cwproc retrieve`` runs before :func:`cwproc.pipeline.run_unit`: a bad file
    fails alone (its line in ``failures``) and never stops the others; a sonic file
    crossing midnight feeds two days. Inputs are kept in memory up to
    :data:`RETRIEVE_MEMORY_BYTES`; beyond it ``.hpl`` files are identified by their
    header and every input is read again when its unit runs (same products).

    Parameters
    ----------
    paths : iterable of path
        Instrument files (any format cwproc reads; detected from their content unless
        the configuration pins ``[instrument] format``).
    config : Config
        The configuration (reader options, pinned format).
    kinds : iterable of str, optional
        Accept only inputs of these kinds (``"scan"``, ``"wind_record"``, ``"sonic"``);
        others are failures. Default: all.

    Returns
    -------
    FoundUnits
        ``(units, failures, notes)``.
    """
    found = FoundUnits([], [], [])
    parts: list[UnitPart] = []
    accepted = set(kinds) if kinds is not None else None
    held = 0
    if isinstance(paths, Sequence):
        paths = progress.track(paths, desc="reading", unit="file")
    for p, item in read_inputs(paths, config):
        if isinstance(item, CwprocError):
            found.failures.append(str(item))
            continue
        if isinstance(item, Exception):  # a reader bug must not stop the other files
            found.failures.append(f"{p}: {internal_error(item)}")
            continue
        if KIND[item.format] == "background":  # not a product input (see correct_background)
            found.notes.append(f"{p}: Stream Line background file, not a product input")
            continue
        mismatch = instrument_mismatch(item, config)
        if mismatch:  # processed with the wrong instrument's settings it would mislead
            found.failures.append(mismatch)
            continue
        if accepted is not None and KIND[item.format] not in accepted:
            found.failures.append(
                f"{p}: {item.format.value} data ({KIND[item.format]}) cannot be used here; "
                f"expected {' or '.join(sorted(accepted))} data"
            )
            continue
        for part in split_by_day(item):
            parts.append(unit_part(part))
            held += _nbytes(part.dataset)
            if held > RETRIEVE_MEMORY_BYTES:  # keep only what the budget allows
                held -= _nbytes(part.dataset)
                part.dataset = None
    found.units.extend(units_of(parts, found.notes))
    return found


#: inputs read whole at once by :func:`read_inputs` (file reads, checksums and parsers
#: run in parallel; each holds at most one file's dataset)
READ_INPUT_THREADS = 2


def read_inputs(
    paths: Iterable[str | os.PathLike], config: Config, threads: int = READ_INPUT_THREADS
) -> Iterator[tuple[str | os.PathLike, InputFile | Exception]]:
    """``(path, read_input(path, identify_only=True, checksum=False))`` of each input,
    in order; the exception a file raised in place of its item. A ``.hpl`` file is
    identified by its header, and its checksum taken when its unit reads its data
    (:func:`cwproc.pipeline.input_files.load_item`,
    :func:`cwproc.pipeline.stream_read.planned_chunks`):
    a day of scans is read once less.

    A file known from its header (:func:`~cwproc.pipeline.input_files.identify_input`) is
    identified in the caller's thread: that is Python-level work, which threads would
    only pass the GIL back and forth for (a day of 1920 ``.hpl`` headers took 0.55-0.70
    s in two threads, 0.31-0.35 s in one). The inputs read whole are read by
    ``threads`` threads, at most ``2 * threads`` ahead of the caller: the checksum
    (``hashlib`` releases the GIL), the file reads and the parsers of one input run
    beside those of the next, on the second core when it is free. The items and errors
    are those of reading the files one by one.
    """
    pending: deque[tuple[str | os.PathLike, object]] = deque()
    reading = 0  # futures in ``pending``
    with ThreadPoolExecutor(max(int(threads), 1), "cwproc-identify") as pool:
        try:
            for p in paths:
                item = _identify_one(p, config)
                if isinstance(item, Examined):  # read whole, by a thread
                    item = pool.submit(_read_one, p, config, item)
                    reading += 1
                pending.append((p, item))
                while pending and (reading > 2 * threads or not _is_future(pending[0][1])):
                    reading -= _is_future(pending[0][1])
                    yield _result(*pending.popleft())
            while pending:
                yield _result(*pending.popleft())
        finally:
            for _, future in pending:
                if _is_future(future):
                    future.cancel()


def _is_future(item: object) -> bool:
    return isinstance(item, Future)


def _identify_one(path: str | os.PathLike, config: Config) -> InputFile | Examined | Exception:
    try:
        return identify_input(path, config)
    except Exception as exc:  # handed to the caller with its path
        return exc


def _read_one(path: str | os.PathLike, config: Config, examined: Examined) -> InputFile | Exception:
    """The item of a file its header could not identify: read whole, with its checksum
    (what ``read_input(..., identify_only=True)`` falls back to), not examined again."""
    try:
        return read_input(path, config, examined=examined)
    except Exception as exc:  # handed to the caller with its path
        return exc


def _result(path: str | os.PathLike, item: object) -> tuple[str | os.PathLike, object]:
    return path, item.result() if _is_future(item) else item


#: variables a dataset of each canonical kind has (declared in its table of
#: :data:`cwproc.metadata.DATASET_VARIABLES`, as a test checks)
_KIND_VARIABLES = {
    "scan": ("radial_velocity", "azimuth", "elevation", "time", "range"),
    "sonic": ("u", "v", "w", "time"),
}
#: sonic formats by the prefix of the attributes their readers set
_SONIC_PREFIXES = (("toa5_", Format.TOA5), ("tob1_", Format.TOB1), ("ghg_", Format.GHG))


def dataset_format(ds: xr.Dataset, label: str = "dataset") -> Format:
    """The input format a canonical dataset was read from (its attributes and variables).

    A wind record names its format (``format``); a scan dataset with a Stream Line
    header is ``hpl``, any other ``scan_netcdf``; a sonic dataset is told by the
    attributes of its reader (``toa5_*``, ``tob1_*``, ``ghg_*``, ``meteo2_*``; else
    ``gill``).

    Raises
    ------
    CwprocError
        ``ds`` is none of the canonical datasets (e.g. a product): the message names
        ``label`` and what a canonical dataset holds.
    """
    stated = str(ds.attrs.get("format", ""))
    if stated in {f.value for f in Format} and KIND[Format(stated)] == "wind_record":
        return Format(stated)
    names = {str(v) for v in ds.variables}
    for kind, needed in _KIND_VARIABLES.items():
        if not set(needed) <= names:
            continue
        if kind == "scan" and "ray" in ds.dims:
            hpl = "header_filename" in ds.attrs or ds.attrs.get("instrument_kind") == "streamline"
            return Format.HPL if hpl else Format.SCAN_NETCDF
        if kind == "sonic" and "sampling_rate_hz" in ds.attrs:
            keys = " ".join(str(k) for k in ds.attrs)
            for prefix, fmt in _SONIC_PREFIXES:
                if prefix in keys:
                    return fmt
            return Format.METEO2 if "meteo2_" in keys else Format.GILL
    raise CwprocError(
        f"{label}: not a dataset cwproc reads (scan: radial_velocity(ray, range); sonic: "
        "u, v, w(time) and sampling_rate_hz; wind record: the format attribute of its "
        "reader); pass what cwproc.read returns"
    )


def dataset_units(
    datasets: Sequence[xr.Dataset], config: Config | None
) -> tuple[list[tuple[ProductUnit, Config]], list[str], list[str]]:
    """Product units of datasets already read (:func:`cwproc.read`), with their configuration.

    Each dataset becomes an :class:`InputFile` holding it, named
    ``<in-memory>/<its source file>`` (``<in-memory>/dataset-<k>`` without one), with no
    checksum; the inputs are grouped as files are (:func:`group_units`: the scans of
    one instrument and day are joined by :func:`cwproc.io.scan_join.concat_scans`, so the
    per-file datasets of one day may be passed as they are).

    Parameters
    ----------
    datasets : sequence of xarray.Dataset
        Canonical scan, wind-record or sonic datasets.
    config : Config or None
        The configuration of every unit; ``None``: each unit's instrument preset
        (:func:`cwproc.config.default_preset`).

    Returns
    -------
    units : list of (ProductUnit, Config)
    failures : list of str
        One line per dataset of another instrument than ``config`` describes.
    notes : list of str
        Without ``config``: which preset each unit took (:func:`preset_note`).

    Raises
    ------
    CwprocError
        A dataset is none of the canonical datasets (the message names it).
    """
    parts: list[UnitPart] = []
    failures: list[str] = []
    for k, ds in enumerate(datasets):
        fmt = dataset_format(ds, f"dataset {k}")
        sources = ds.attrs.get("source_files")
        named = [str(s) for s in sources] if isinstance(sources, list | tuple) else []
        name = Path(named[0]).name if len(named) == 1 else f"dataset-{k}"
        time = ds["time"].values if "time" in ds.variables else None
        item = InputFile(
            path=IN_MEMORY / name,
            format=fmt,
            sha256=None,
            dataset=ds,
            start=time.min() if time is not None and time.size else None,
        )
        mismatch = instrument_mismatch(item, config) if config is not None else ""
        if mismatch:
            failures.append(mismatch)
            continue
        parts.extend(unit_part(part) for part in split_by_day(item))
    chosen: list[tuple[ProductUnit, Config]] = []
    notes: list[str] = []
    for unit in units_of(parts):
        if config is None:
            first = unit.inputs[0]
            attrs = dict(first.dataset.attrs) if first.dataset is not None else {}
            preset = default_preset(first.format.value, attrs)
            chosen.append((unit, load_config(preset)))
            notes.append(preset_note(preset, [os.fspath(i.path) for i in unit.inputs]))
        else:
            chosen.append((unit, config))
    return chosen, failures, notes


def preset_note(preset: str, files: Sequence[str]) -> str:
    """The note that ``files`` were processed with ``preset`` (no configuration given)."""
    names = ", ".join(files[:3]) + (f" (+{len(files) - 3} more)" if len(files) > 3 else "")
    return (
        f"no configuration given: preset {preset} for {names}; pass config= to choose "
        "another (cwproc.preset_names())"
    )


def default_presets(paths: Iterable[str | os.PathLike]) -> dict[str, list[str]]:
    """The files of ``paths`` by the preset of their instrument (no configuration given).

    The format of each file is recognised from its content
    (:func:`cwproc.config.default_preset`; a scan NetCDF file by the instrument its
    attributes state). A file that cannot be recognised goes with the defaults (key
    ``""``: :class:`Config`), whose read then names its problem.
    """
    groups: dict[str, list[str]] = {}
    for path in paths:
        try:
            fmt = detect_format(path)
        except CwprocError:
            groups.setdefault("", []).append(os.fspath(path))
            continue
        attrs = netcdf_attributes(path) if fmt is Format.SCAN_NETCDF else {}
        groups.setdefault(default_preset(fmt.value, attrs), []).append(os.fspath(path))
    return groups


def netcdf_attributes(path: str | os.PathLike) -> dict[str, object]:
    """The global attributes of a NetCDF file ({} when it cannot be opened)."""
    import netCDF4

    try:
        with NETCDF_LOCK, netCDF4.Dataset(path) as nc:
            return {k: nc.getncattr(k) for k in nc.ncattrs()}
    except OSError:
        return {}
