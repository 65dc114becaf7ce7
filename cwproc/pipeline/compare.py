"""Lidar against sonic: read the two products, match them, write the comparison product.

Used by ``cwproc compare``; the matching is the stage
:func:`cwproc.stages.lidar_sonic.compare_lidar_sonic`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.io.netcdf import read_product
from cwproc.products.catalogue import describe_product
from cwproc.products.writer import write_product
from cwproc.stages.lidar_sonic import compare_lidar_sonic


def _read(path: str | os.PathLike, what: str) -> xr.Dataset:
    """A product, or a CwprocError naming the file and the problem."""
    try:
        return read_product(path)
    except (OSError, ValueError) as exc:
        raise CwprocError(f"{path}: cannot read the {what} product: {exc}") from None


def compare_files(
    lidar_path: str | os.PathLike,
    sonic_path: str | os.PathLike,
    outdir: str | os.PathLike,
    *,
    height_m: float,
    max_height_offset_m: float = 25.0,
    exclude_flag_mask: int | None = None,
) -> tuple[xr.Dataset, Path]:
    """Write ``lidar-sonic_<YYYYMMDD>_<H>m.nc`` in ``outdir``; return it and its path.

    Raises
    ------
    CwprocError
        A file cannot be read, lacks a variable, or no lidar height is near H (the
        message names the file).
    """
    lidar = _read(lidar_path, "lidar turbulence")
    sonic = _read(sonic_path, "sonic turbulence")
    try:
        ds = compare_lidar_sonic(
            lidar,
            sonic,
            height_m=height_m,
            max_height_offset_m=max_height_offset_m,
            **({} if exclude_flag_mask is None else {"exclude_flag_mask": exclude_flag_mask}),
        )
    except CwprocError as exc:
        raise CwprocError(f"{lidar_path} vs {sonic_path}: {exc}") from None
    day = np.datetime_as_string(np.asarray(ds["time"].values)[0], unit="D").replace("-", "")
    target = Path(outdir) / f"lidar-sonic_{day}_{height_m:g}m.nc"
    described = describe_product("lidar_sonic", "scan")
    write_product(
        ds,
        target,
        product="lidar_sonic",
        title=described.title,
        summary=described.summary,
        keywords=described.keywords,
        references=described.references,
        inputs=[lidar_path, sonic_path],
    )
    return ds, target
