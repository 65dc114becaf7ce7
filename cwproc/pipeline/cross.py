"""Cross-polarised Stream Line files for the depolarisation ratio of the L1 product.

A Stream Line with a polariser writes its cross-polarised stares as ``.hpl`` files of the
same names as the co-polarised ones (Cloudnet sites upload them tagged ``co`` and
``cross``), so they are kept in their own folder, ``[doppler_lidar] cross_folder``
(``cwproc retrieve --cross DIR``), with their own ``Background_*.txt`` beside them. This
module finds the files of a unit's instrument and day there, reads them, corrects their
SNR with those backgrounds (Manninen et al. (2016)) and hands the rays to
:func:`cwproc.pipeline.chain.process_scan_day`, which pairs them with the co rays.
"""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.pipeline.background_files import correct_background, find_background_files
from cwproc.pipeline.input_files import read_input
from cwproc.pipeline.product_units import ProductUnit, concat_unit, load_unit, unit_key


def cross_files(folder: str | Path) -> list[Path]:
    """The ``.hpl`` files of a cross-polarised folder, sorted."""
    return sorted(p for p in Path(folder).glob("*.hpl") if p.is_file())


def cross_scans(unit: ProductUnit, config: Config, notes: list[str] | None) -> xr.Dataset | None:
    """The background-corrected cross-polarised scans of ``unit``'s instrument and day.

    None when ``[doppler_lidar]`` is off or has no ``cross_folder``, or when the folder
    holds no file of this unit (a note says so). A damaged file is named in a note and
    left out, as the background files are.
    """
    opts = config.doppler_lidar
    if unit.kind != "scan" or not opts.enabled or not opts.cross_folder:
        return None
    folder = Path(opts.cross_folder)
    if not folder.is_dir():
        if notes is not None:
            notes.append(f"depolarisation not computed: --cross {folder} is not a folder")
        return None
    lines: list[str] = []
    items = []
    for path in cross_files(folder):
        try:
            item = read_input(path, config, identify_only=True)
        except CwprocError as exc:
            lines.append(f"cross-polarised file not used: {exc}")
            continue
        if unit_key(item) == (unit.kind, unit.key):
            items.append(item)
    cross = ProductUnit(key=unit.key, kind="scan", inputs=items)
    load_unit(cross, config)
    lines.extend(f"cross-polarised file not used: {f}" for f in cross.failures)
    if not cross.inputs:
        lines.append(
            f"depolarisation not computed: no cross-polarised file of {unit.key} in {folder}"
        )
        ds = None
    else:
        ds = concat_unit(cross)
        bg_notes: list[str] = []
        ds = correct_background(
            ds, cross, config, bg_notes, files=find_background_files([], folder)
        )
        lines.extend(f"cross-polarised: {n}" for n in bg_notes)
        ds.attrs["cross_files"] = [str(i.path.name) for i in cross.inputs]
    if notes is not None:
        notes.extend(lines)
    return ds
