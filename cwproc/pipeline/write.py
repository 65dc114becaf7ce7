"""Writing the products of a unit: all or none, with provenance and CF metadata."""

from __future__ import annotations

import os
import re
from pathlib import Path

import xarray as xr

from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.io.netcdf import discard, publish
from cwproc.pipeline.input_files import held_or_identity
from cwproc.pipeline.product_units import ProductUnit
from cwproc.products.catalogue import describe_product, product_kind
from cwproc.products.writer import add_site_coordinates, site_attributes, write_product

#: a product file name: no separator, no leading dot, nothing a shell or a filesystem
#: would take for something else
_PLAIN_NAME = re.compile(r"[A-Za-z0-9_+@-][A-Za-z0-9._+@-]*")


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


#: the folder named by the inputs passed as datasets (no file is there, so no background
#: file or checksum is looked for)
IN_MEMORY = Path("<in-memory>")
#: the ``input_sha256`` entry of an input passed as a dataset (no file to checksum)
IN_MEMORY_CHECKSUM = "none: passed to cwproc.retrieve as a dataset in memory"


def input_checksums(unit: ProductUnit) -> dict[str, str]:
    """``{path: sha256}`` of the inputs whose checksum is known, and of those passed as
    datasets (:func:`cwproc.pipeline.retrieve.dataset_units`, folder ``<in-memory>``):
    :data:`IN_MEMORY_CHECKSUM`. The writer takes the others' checksums from their files."""
    sums = {}
    for item in unit.inputs:
        if item.sha256:
            sums[os.fspath(item.path)] = item.sha256
        elif Path(item.path).parent == IN_MEMORY:
            sums[os.fspath(item.path)] = IN_MEMORY_CHECKSUM
    return sums


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
                    product=product_kind(name, unit.kind),
                    title=f"cwproc {about.title}: {unit.key}",
                    summary=about.summary,
                    inputs=list(dict.fromkeys(i.path for i in unit.inputs)),
                    # a checksum not taken yet is taken by the writer
                    checksums=input_checksums(unit),
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
