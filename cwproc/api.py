"""The Python interface of cwproc: read files, retrieve products, write them.

What ``cwproc retrieve`` does, step by step in a notebook::

    import cwproc

    scans = cwproc.read("sample_data/streamline/VAD_999_20240601_120000.hpl")
    config = cwproc.Config.preset("streamline").replace(vad={"min_rays": 8})
    result = cwproc.retrieve(["sample_data/streamline"], config)
    wind = result["wind"]                      # an xarray.Dataset with CF units
    cwproc.write(result, "out/")               # the NetCDF files of cwproc retrieve

:func:`retrieve` runs the same chain of stages as the command line
(:mod:`cwproc.pipeline`) and returns the products instead of writing them; the stage
functions themselves (``cwproc.stages``) take plain keyword arguments whose defaults
are those of the instrument presets.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import xarray as xr

from cwproc.config import Config, load_config
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import FileIdentity, is_regular_file, read_file
from cwproc.pipeline import (
    InputFile,
    ProductUnit,
    read_units,
    run_unit,
    write_unit_products,
)
from cwproc.pipeline.file_search import expand_inputs
from cwproc.products.catalogue import product_kind
from cwproc.products.metadata import apply_metadata
from cwproc.products.writer import add_site_coordinates

__all__ = ["Retrieval", "UnitProducts", "read", "retrieve", "write"]


def read(path: str | os.PathLike, *, format: str = "auto", **options: Any) -> xr.Dataset:
    """One instrument file as its canonical dataset (scan, wind record or sonic).

    Parameters
    ----------
    path : str or path
        The file (Stream Line ``.hpl``, cwproc scan NetCDF, ZephIR or WindCube export,
        Campbell TOA5/TOB1, LI-COR GHG, Gill or Meteo-2 log).
    format : str
        ``"auto"`` recognises the format from the file's content; else one of the
        formats of ``[instrument] format`` (``"hpl"``, ``"meteo2"``, ...).
    **options
        Options of that format's reader, as in the ``[reader.<format>]`` table of a
        configuration (e.g. ``delimiter=","`` for Meteo-2).

    Returns
    -------
    xarray.Dataset
        The canonical dataset of the file's kind (see ``docs/variables.md``).

    Raises
    ------
    InputFileError
        The file is missing, not a regular file, of no format cwproc reads, or damaged
        (the message names the file, the line and the problem).
    """
    if not is_regular_file(path):
        raise InputFileError(path, "not a regular file (a folder, pipe, socket or device)")
    return read_file(path, format, **options)


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
    #: the input files of the unit
    inputs: tuple[Path, ...]
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
    #: the configuration used
    config: Config

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
            f"config {self.config.source}>"
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


def _config(config: Config | str | os.PathLike | None) -> Config:
    """A validated configuration from a :class:`Config`, a preset name, a path or None."""
    if config is None:
        return Config()
    if isinstance(config, Config):
        return config.checked()
    return load_config(config)


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


def _find_units(paths: list[str], config: Config) -> tuple[list[ProductUnit], list[str], list[str]]:
    """``(units, failures, notes)`` of the files named or found under ``paths``.

    The files ``cwproc retrieve`` would take (:func:`cwproc.pipeline.expand_inputs`),
    read and grouped as it does (:func:`cwproc.pipeline.read_units`).

    Raises
    ------
    CwprocError
        Nothing to process: no input file, or only files of a format the configuration
        does not read.
    """
    found = expand_inputs(tuple(paths), config)
    nothing = found.nothing_readable()
    if nothing:
        raise CwprocError(nothing)
    if not found.files and not found.mismatched:
        raise CwprocError(f"no input files found in {', '.join(paths)}{found.skipped_text()}")
    read = read_units(found.files, config)
    return read.units, [*found.mismatched, *read.failures], [*found.skipped_notes, *read.notes]


def retrieve(
    files: str | os.PathLike | Iterable[str | os.PathLike],
    config: Config | str | os.PathLike | None = None,
    *,
    errors: Literal["raise", "collect"] = "raise",
) -> Retrieval:
    """Wind, turbulence, stare and structure-function products of instrument files.

    The products ``cwproc retrieve`` writes, returned instead of written: files are
    recognised by their content, grouped into units (the scans of one instrument and
    UTC day; one wind-record file; the sonic data of one station and day) and each unit
    runs the stage chain of :mod:`cwproc.pipeline`.

    Parameters
    ----------
    files : path or iterable of paths
        Files, or folders searched recursively (files of no known format and cwproc's
        own products are skipped there).
    config : Config, str or path, optional
        A :class:`Config` (built in Python), a preset name (``"streamline"``,
        ``"zephir300"``, ``"meteo2"``, ...) or a TOML file; ``None``: the defaults
        (Stream Line).
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
        No input file was found, or (with ``errors="raise"``) an input or unit failed.
    """
    cfg = _config(config)
    found, failures, notes = _find_units(_input_paths(files), cfg)
    units: dict[str, UnitProducts] = {}
    for unit in found:
        result = run_unit(unit, cfg)
        failures.extend(result.failures)
        unit.inputs[:] = [_released(i) for i in unit.inputs]
        if not result.products:
            notes.extend(result.notes)
            continue
        units[unit.key] = UnitProducts(
            key=unit.key,
            kind=unit.kind,
            products={
                name: apply_metadata(
                    add_site_coordinates(ds, cfg.output), product=product_kind(name, unit.kind)
                )
                for name, ds in result.products.items()
            },
            notes=tuple(result.notes),
            inputs=tuple(dict.fromkeys(i.path for i in unit.inputs)),
            _unit=unit,
        )
    if failures and errors == "raise":
        more = f" (+{len(failures) - 1} more failures)" if len(failures) > 1 else ""
        raise CwprocError(f"{failures[0]}{more}; retrieve(..., errors='collect') lists them")
    return Retrieval(units=units, failures=tuple(failures), notes=tuple(notes), config=cfg)


def write(products: Retrieval, outdir: str | os.PathLike) -> list[Path]:
    """Write the products of :func:`retrieve` as ``cwproc retrieve`` does.

    Every unit's products are written together (all or none), as CF-1.10 / ACDD-1.3
    NetCDF files ``OUTDIR/<unit key>_<product>.nc`` with the provenance of their inputs
    and the configuration.

    Parameters
    ----------
    products : Retrieval
        What :func:`retrieve` returned.
    outdir : str or path
        Folder of the products (created if missing).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    Path(outdir).mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for unit in products.units.values():
        written.extend(write_unit_products(unit._unit, unit.products, outdir, products.config))
    return written
