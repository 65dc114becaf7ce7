"""The Python interface of cwproc: read files, retrieve products, write them.

What ``cwproc retrieve`` does, step by step in a notebook::

    import cwproc

    scans = cwproc.read("sample_data/streamline/*.hpl")   # one record, scans numbered
    wind = cwproc.stages.fit_vad(scans)                 # 12 scans -> 12 wind profiles
    config = cwproc.Config.preset("streamline").replace(vad={"min_rays": 8})
    result = cwproc.retrieve(["sample_data/streamline"], config)
    wind = result["wind"]                      # an xarray.Dataset with CF units
    cwproc.write(result, "out/")               # the NetCDF files of cwproc retrieve

:func:`retrieve` runs the same chain of stages as the command line
(:mod:`cwproc.pipeline`) and returns the products instead of writing them; the stage
functions themselves (``cwproc.stages``) take plain keyword arguments whose defaults
are those of the instrument presets, and their outputs carry the units and long names
of the metadata table (:mod:`cwproc.metadata`).

Join the files of a record with :func:`read` (or :func:`cwproc.io.scan_join.concat_scans`),
never ``xarray.concat``: every file numbers its scans from 0, and the scan stages refuse
a dataset whose scan numbers collide across files (:mod:`cwproc.stages.scan_guard`).
"""

from __future__ import annotations

import dataclasses
import glob
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import xarray as xr

from cwproc.config import Config, load_config
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import KIND, FileIdentity, Format, detect_format, is_regular_file, read_file
from cwproc.io.scan_join import concat_scans
from cwproc.metadata import PRODUCTS, apply_metadata
from cwproc.pipeline import (
    InputFile,
    ProductUnit,
    read_units,
    run_unit,
    write_unit_products,
)
from cwproc.pipeline.file_search import expand_inputs
from cwproc.pipeline.product_units import concat_sonic, name_part
from cwproc.pipeline.retrieve import dataset_units, default_presets, preset_note
from cwproc.products.catalogue import describe_product, product_kind
from cwproc.products.writer import add_site_coordinates, write_product

__all__ = ["Retrieval", "UnitProducts", "read", "retrieve", "write"]


def read(
    paths: str | os.PathLike | Sequence[str | os.PathLike], *, format: str = "auto", **options: Any
) -> xr.Dataset:
    """Instrument files as one canonical dataset (scan, wind record or sonic).

    Like :func:`xarray.open_mfdataset` for cwproc's inputs: several scan files become
    one scan dataset whose scans are numbered over the whole record (rays in time
    order, :func:`cwproc.io.scan_join.concat_scans`), so that scan ``k`` of one file is
    never merged with scan ``k`` of the next, as ``xarray.concat`` would do.

    Parameters
    ----------
    paths : path, glob pattern or sequence of paths
        One file (Stream Line ``.hpl``, cwproc scan NetCDF, ZephIR or WindCube export,
        Campbell TOA5/TOB1, LI-COR GHG, Gill or Meteo-2 log); a pattern such as
        ``"data/*.hpl"`` (``**`` for any depth), its matches sorted; or a list of files.
        Several files must be of one kind: scans (joined as above, in one pass for
        ``.hpl`` files, :func:`cwproc.io.halo_files.read_hpl_files`) or sonic samples
        of one format (joined in time order at one sampling rate). A wind-record file is
        read on its own.
    format : str
        ``"auto"`` recognises each file's format from its content; else one of the
        formats of ``[instrument] format`` (``"hpl"``, ``"meteo2"``, ...).
    **options
        Options of that format's reader, as in the ``[reader.<format>]`` table of a
        configuration (e.g. ``delimiter=","`` for Meteo-2).

    Returns
    -------
    xarray.Dataset
        The canonical dataset of the files' kind (see ``docs/variables.md``).

    Raises
    ------
    InputFileError
        A file is missing, not a regular file, of no format cwproc reads, or damaged
        (the message names the file, the line and the problem); a pattern matches no
        file; the files are of different kinds or (sonic) formats, or are wind records.
    CwprocError
        No file given, or scans that cannot be joined (another range grid, system id or
        detection; the message names the files).
    """
    files = _read_paths(paths)
    if len(files) == 1:
        if not is_regular_file(files[0]):
            raise InputFileError(files[0], "not a regular file (a folder, pipe, socket or device)")
        return read_file(files[0], format, **options)
    return _read_many(files, format, options)


def _read_many(files: list[str], format: str, options: dict[str, Any]) -> xr.Dataset:
    """Several files of one kind as one dataset (see :func:`read`)."""
    for path in files:
        if not is_regular_file(path):
            raise InputFileError(path, "not a regular file (a folder, pipe, socket or device)")
    formats = [detect_format(f) if format in (None, "auto") else Format(format) for f in files]
    kind = KIND[formats[0]]
    for path, fmt in zip(files, formats, strict=True):
        if KIND[fmt] != kind:
            raise InputFileError(
                path,
                f"a {KIND[fmt]} file ({fmt.value}), but {files[0]} is a {kind} file "
                f"({formats[0].value}): read the files of each kind on their own",
            )
    if kind == "scan":
        if all(fmt is Format.HPL for fmt in formats):
            from cwproc.io.halo_files import read_hpl_files

            return read_hpl_files(files, **options)
        return concat_scans(
            [read_file(f, fmt, **options) for f, fmt in zip(files, formats, strict=True)]
        )
    if kind == "sonic":
        for path, fmt in zip(files, formats, strict=True):
            if fmt is not formats[0]:
                raise InputFileError(
                    path,
                    f"a {fmt.value} file, but {files[0]} is a {formats[0].value} file: "
                    "sonic files are joined when they come from one logger",
                )
        parts = [read_file(f, fmt, **options) for f, fmt in zip(files, formats, strict=True)]
        return concat_sonic(parts, f"{files[0]} (+{len(files) - 1} more)")
    raise InputFileError(
        files[1],
        f"{len(files)} {kind.replace('_', ' ')} files given: each is read (and processed) "
        "on its own; read them one at a time",
    )


def _read_paths(paths: str | os.PathLike | Sequence[str | os.PathLike]) -> list[str]:
    """The files :func:`read` is asked for: one path, a glob's matches, or a sequence."""
    if isinstance(paths, str | os.PathLike):
        text = os.fspath(paths)
        if not any(c in text for c in "*?[") or os.path.lexists(text):
            return [text]
        found = sorted(glob.glob(os.path.expanduser(text), recursive=True))
        if not found:
            raise InputFileError(text, "no file matches this pattern")
        return found
    if isinstance(paths, xr.Dataset | xr.DataArray) or not isinstance(paths, Iterable):
        raise TypeError(
            f"cwproc.read takes a path, a glob pattern or a sequence of paths, not "
            f"{type(paths).__name__}"
        )
    files = list(paths)
    for item in files:
        if not isinstance(item, str | os.PathLike):
            raise TypeError(
                f"cwproc.read takes a sequence of paths; it holds a {type(item).__name__}"
            )
    if not files:
        raise CwprocError("cwproc.read: no file given")
    return [os.fspath(f) for f in files]


@dataclass(frozen=True)
class UnitProducts:
    """The products of one unit (e.g. one instrument-day of scans) and its notes."""

    #: the unit's name, the start of its product file names (``<key>_wind.nc``)
    key: str
    #: ``"scan"``, ``"wind_record"`` or ``"sonic"``
    kind: str
    #: product name (``"wind"``, ``"turbulence"``, ``"stare"``, ``"sf"``) -> dataset
    products: dict[str, xr.Dataset]
    #: what the user should know that is not a failure (e.g. turbulence not computed)
    notes: tuple[str, ...]
    #: the input files of the unit (``<in-memory>/...`` for datasets passed to retrieve)
    inputs: tuple[Path, ...]
    #: the configuration the unit ran with (its instrument's preset when none was given)
    config: Config
    _unit: ProductUnit = field(repr=False, compare=False)

    def __repr__(self) -> str:
        files = ", ".join(p.name for p in map(Path, self.inputs))
        return (
            f"<UnitProducts {self.key} ({self.kind}): {', '.join(self.products) or 'none'} "
            f"from {files}>"
        )


@dataclass(frozen=True)
class Retrieval:
    """What :func:`retrieve` made: the products of every unit, notes and failures.

    ``result["wind"]`` is the wind product when exactly one unit made one;
    ``result.units[key].products[name]`` reaches any product.
    """

    #: unit key -> its products and notes, in the order of the command line's output
    units: dict[str, UnitProducts]
    #: one line per input or unit that failed (file, line, problem)
    failures: tuple[str, ...]
    #: notes about inputs that belong to no unit (e.g. Stream Line background files)
    notes: tuple[str, ...]
    #: the configuration given; None: each unit ran with its instrument's preset
    #: (:attr:`UnitProducts.config`, named in :attr:`notes`)
    config: Config | None

    @property
    def ok(self) -> bool:
        """True when no input and no unit failed."""
        return not self.failures

    def all_notes(self) -> list[str]:
        """Every note, the run's first, then each unit's (every note names its files)."""
        return list(self.notes) + [note for u in self.units.values() for note in u.notes]

    def __repr__(self) -> str:
        units = "; ".join(
            f"{key} [{', '.join(u.products) or 'no product'}]" for key, u in self.units.items()
        )
        return (
            f"<Retrieval: {len(self.units)} unit(s): {units or 'none'}; "
            f"{len(self.failures)} failure(s); {len(self.all_notes())} note(s); "
            f"config {self.config.source if self.config else 'per unit'}>"
        )

    def __getitem__(self, name: str) -> xr.Dataset:
        """The product ``name`` of the one unit that made it.

        Raises
        ------
        KeyError
            No unit, or more than one, made a product of that name (then use
            ``units[key].products[name]``).
        """
        found = [u for u in self.units.values() if name in u.products]
        if len(found) != 1:
            made = sorted({n for u in self.units.values() for n in u.products})
            why = "no unit made" if not found else f"{len(found)} units made"
            raise KeyError(
                f"{why} a {name!r} product (products: {', '.join(made) or 'none'}; "
                f"units: {', '.join(self.units) or 'none'}); use .units[key].products[name]"
            )
        return found[0].products[name]


def _config(config: Config | str | os.PathLike | None) -> Config | None:
    """A validated configuration from a :class:`Config`, a preset name or a path (None: None)."""
    if config is None:
        return None
    if isinstance(config, Config):
        return config.checked()
    return load_config(config)


def _datasets(data: object) -> list[xr.Dataset] | None:
    """The datasets passed to :func:`retrieve`, or None when it was given paths.

    Raises
    ------
    TypeError
        Neither paths nor datasets (or a mixture); the message names what is accepted.
    """
    if isinstance(data, xr.Dataset):
        return [data]
    if isinstance(data, str | os.PathLike):
        return None
    if isinstance(data, xr.DataArray) or not isinstance(data, Iterable):
        raise TypeError(_ACCEPTED + f", not {type(data).__name__}")
    items = list(data)
    if items and all(isinstance(d, xr.Dataset) for d in items):
        return items
    for item in items:
        if not isinstance(item, str | os.PathLike):
            raise TypeError(_ACCEPTED + f"; the sequence holds a {type(item).__name__}")
    return None


_ACCEPTED = (
    "cwproc.retrieve takes a path (file or folder), a sequence of paths, a dataset of "
    "cwproc.read or a sequence of them"
)


def _input_paths(files: str | os.PathLike | Iterable[str | os.PathLike]) -> list[str]:
    if isinstance(files, str | os.PathLike):
        return [os.fspath(files)]
    return [os.fspath(f) for f in files]


def _released(item: InputFile) -> InputFile:
    """``item`` without its data, keeping the attributes the writer names it by."""
    if item.dataset is None:
        return item
    identity = FileIdentity(attrs=dict(item.dataset.attrs), time=np.array([], "datetime64[ns]"))
    return dataclasses.replace(item, dataset=None, identity=item.identity or identity)


def _find_units(
    paths: list[str], config: Config | None
) -> tuple[list[tuple[ProductUnit, Config]], list[str], list[str]]:
    """``(units with their configuration, failures, notes)`` of the files under ``paths``.

    The files ``cwproc retrieve`` would take (:func:`cwproc.pipeline.expand_inputs`),
    read and grouped as it does (:func:`cwproc.pipeline.read_units`). Without a
    configuration, the files of each instrument are read and run with its preset
    (:func:`cwproc.config.default_preset`), and a note says which.

    Raises
    ------
    CwprocError
        Nothing to process: no input file, or only files of a format the configuration
        does not read.
    """
    found = expand_inputs(tuple(paths), config or Config())
    nothing = found.nothing_readable()
    if nothing:
        raise CwprocError(nothing)
    if not found.files and not found.mismatched:
        raise CwprocError(f"no input files found in {', '.join(paths)}{found.skipped_text()}")
    groups = {"": list(found.files)} if config is not None else default_presets(found.files)
    units: list[tuple[ProductUnit, Config]] = []
    failures, notes = list(found.mismatched), list(found.skipped_notes)
    for preset, files in groups.items():
        cfg = config or _preset_config(preset, files)
        read = read_units(files, cfg)
        units.extend((unit, cfg) for unit in read.units)
        failures.extend(read.failures)
        notes.extend(read.notes)
        if config is None and preset:
            notes.append(preset_note(preset, files))
    return units, failures, notes


def _preset_config(preset: str, files: list[str]) -> Config:
    """The configuration of files of one instrument: its preset, reading every format
    of that instrument (a Stream Line's scan NetCDF files too); ``""``: the defaults."""
    if not preset:
        return Config()
    cfg = load_config(preset)
    pinned = cfg.instrument.format
    if pinned != "auto" and any(
        detect_format(f).value not in (pinned, "halo_background") for f in files
    ):
        cfg = cfg.replace(instrument={"format": "auto"})
    return cfg


def retrieve(
    data: str | os.PathLike | Iterable[str | os.PathLike] | xr.Dataset | Sequence[xr.Dataset],
    config: Config | str | os.PathLike | None = None,
    *,
    errors: Literal["raise", "collect"] = "raise",
) -> Retrieval:
    """Wind, turbulence, stare and structure-function products of instrument data.

    The products ``cwproc retrieve`` writes, returned instead of written: files are
    recognised by their content, grouped into units (the scans of one instrument and
    UTC day; one wind-record file; the sonic data of one station and day) and each unit
    runs the stage chain of :mod:`cwproc.pipeline`. Datasets already read
    (:func:`read`) are grouped the same way (the per-file scan datasets of a day are
    joined with their scans numbered over the day).

    Parameters
    ----------
    data : path, iterable of paths, Dataset or sequence of Datasets
        Files, or folders searched recursively (files of no known format and cwproc's
        own products are skipped there); or canonical datasets (scan, wind record,
        sonic) as :func:`read` returns them.
    config : Config, str or path, optional
        A :class:`Config` (built in Python), a preset name (``"streamline"``,
        ``"zephir300"``, ``"meteo2"``, ...) or a TOML file; ``None``: each unit takes
        the preset of its instrument (Stream Line ``.hpl``: ``streamline``; ZephIR:
        ``zephir300``; WindCube: ``windcube``; Meteo-2: ``meteo2``; Campbell, LI-COR and
        Gill sonic logs: ``csat3``; a scan NetCDF file by the instrument it states), as
        a note says.
    errors : {"raise", "collect"}
        ``"raise"``: a failed input or unit raises :class:`CwprocError` naming it;
        ``"collect"``: failures are listed in :attr:`Retrieval.failures` and the other
        units' products returned.

    Returns
    -------
    Retrieval
        The products of every unit (CF attributes attached, as they would be written),
        with the notes of the run.

    Raises
    ------
    ConfigError
        The configuration is invalid (the dotted key is named).
    CwprocError
        No input file was found, a dataset is not a canonical one, or (with
        ``errors="raise"``) an input or unit failed.
    TypeError
        ``data`` is neither paths nor datasets.
    """
    cfg = _config(config)
    datasets = _datasets(data)
    if datasets is not None:
        found, failures, notes = dataset_units(datasets, cfg)
    else:
        found, failures, notes = _find_units(_input_paths(data), cfg)  # type: ignore[arg-type]
    units: dict[str, UnitProducts] = {}
    for unit, unit_config in found:
        result = run_unit(unit, unit_config)
        failures.extend(result.failures)
        if datasets is None:
            unit.inputs[:] = [_released(i) for i in unit.inputs]
        if not result.products:
            notes.extend(result.notes)
            continue
        units[unit.key] = UnitProducts(
            key=unit.key,
            kind=unit.kind,
            products={
                name: apply_metadata(
                    add_site_coordinates(ds, unit_config.output),
                    product=product_kind(name, unit.kind),
                )
                for name, ds in result.products.items()
            },
            notes=tuple(result.notes),
            inputs=tuple(dict.fromkeys(i.path for i in unit.inputs)),
            config=unit_config,
            _unit=unit,
        )
    if failures and errors == "raise":
        more = f" (+{len(failures) - 1} more failures)" if len(failures) > 1 else ""
        raise CwprocError(f"{failures[0]}{more}; retrieve(..., errors='collect') lists them")
    return Retrieval(units=units, failures=tuple(failures), notes=tuple(notes), config=cfg)


def write(
    products: Retrieval | UnitProducts | xr.Dataset | Mapping[str, xr.Dataset],
    outdir: str | os.PathLike,
    *,
    product: str | None = None,
    config: Config | str | os.PathLike | None = None,
) -> list[Path]:
    """Write products as ``cwproc retrieve`` does: CF-1.10 / ACDD-1.3 NetCDF files.

    Parameters
    ----------
    products : Retrieval, UnitProducts, Dataset or mapping of name to Dataset
        What :func:`retrieve` returned (every unit's products are written together,
        all or none, as ``OUTDIR/<unit key>_<product>.nc`` with the provenance of their
        inputs and the unit's configuration), one of its units, or products made by the
        stages in a notebook: a dataset (``product=`` names it) or ``{product name:
        dataset}``, written as ``OUTDIR/<first source file>_<product>.nc``.
    outdir : str or path
        Folder of the products (created if missing).
    product : str, optional
        Which product a dataset is, one of :data:`cwproc.metadata.PRODUCTS`
        (``"wind"``, ``"turbulence"``, ``"stare"``, ``"sf"``, ...): it selects the
        metadata declarations. Only for a dataset.
    config : Config, str or path, optional
        For datasets: the configuration recorded in the files (``cwproc_config``) and
        whose ``[output]`` site and compression apply; None: none recorded.

    Returns
    -------
    list of pathlib.Path
        The files written.

    Raises
    ------
    CwprocError
        A dataset without ``product=``, or a product the metadata does not declare.
    TypeError
        ``products`` is none of the above.
    """
    Path(outdir).mkdir(parents=True, exist_ok=True)
    if isinstance(products, xr.Dataset):
        return [_write_dataset(products, outdir, product, _config(config))]
    if product is not None:
        raise TypeError("write(..., product=) names the product of a dataset only")
    if isinstance(products, Retrieval | UnitProducts):
        units = [products] if isinstance(products, UnitProducts) else products.units.values()
        written: list[Path] = []
        for unit in units:
            written.extend(write_unit_products(unit._unit, unit.products, outdir, unit.config))
        return written
    if isinstance(products, Mapping) and all(isinstance(d, xr.Dataset) for d in products.values()):
        cfg = _config(config)
        return [_write_dataset(ds, outdir, str(name), cfg) for name, ds in products.items()]
    raise TypeError(
        "cwproc.write takes what cwproc.retrieve returned, one of its units, a dataset "
        f"(with product=) or a mapping of product name to dataset, not {type(products).__name__}"
    )


def _write_dataset(
    ds: xr.Dataset, outdir: str | os.PathLike, product: str | None, config: Config | None
) -> Path:
    """Write one product dataset made in a notebook; returns its path."""
    if product is None:
        raise CwprocError(
            f"cwproc.write of a dataset needs product=, the product it is: {', '.join(PRODUCTS)}"
        )
    if product not in PRODUCTS:
        raise CwprocError(
            f"unknown product {product!r}: the metadata declares {', '.join(PRODUCTS)}"
        )
    sources = ds.attrs.get("source_files")
    first = str(sources[0]) if isinstance(sources, list | tuple) and sources else "cwproc"
    stem = name_part(Path(first).stem, "cwproc")
    unit_kind = "wind_record" if product == "wind_record" else "scan"
    about = describe_product(product, unit_kind)
    if config is not None:
        ds = add_site_coordinates(ds, config.output)
    return write_product(
        ds,
        Path(outdir) / f"{stem}_{product}.nc",
        product=product,
        title=f"cwproc {about.title}: {stem}",
        summary=about.summary,
        config_toml=config.to_toml() if config is not None else "",
        references=about.references,
        keywords=about.keywords,
        compression_level=config.output.compression_level if config is not None else 4,
    )
