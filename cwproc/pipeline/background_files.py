"""Stream Line background files for the SNR correction of the scans beside them.

The pipeline finds and reads the background files (``*Background_*.txt``, Manninen et
al. (2016); Vakkari et al. (2019)) and hands the datasets to the stage
:func:`cwproc.stages.snr_correction.correct_snr`, which does no I/O.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.io.halo_background import background_time, read_halo_background
from cwproc.pipeline.product_units import ProductUnit
from cwproc.stages.snr_correction import correct_snr, correction_summary, match_rays

#: file-name pattern of Stream Line background files (any prefix, e.g. a site name)
BACKGROUND_GLOB = "*Background_*.txt"


def find_background_files(
    data_files: Iterable[str | os.PathLike], folder: str | os.PathLike | None = None
) -> list[Path]:
    """Background files beside the data files (or in ``folder`` when given), sorted."""
    folders = {Path(folder)} if folder else {Path(p).absolute().parent for p in data_files}
    found: set[Path] = set()
    for f in folders:
        found.update(p for p in f.glob(BACKGROUND_GLOB) if p.is_file())
    return sorted(found)


def missing_folder_note(folder: str | os.PathLike) -> str:
    """Why the configured ``[background] folder`` gave no background file."""
    if not Path(folder).is_dir():
        return f"SNR not corrected: [background] folder {os.fspath(folder)} is not a folder"
    return (
        f"SNR not corrected: no background file ({BACKGROUND_GLOB}) in [background] folder "
        f"{os.fspath(folder)}"
    )


def read_backgrounds(
    paths: Sequence[str | os.PathLike],
    notes: list[str] | None = None,
    *,
    ray_time: np.ndarray | None = None,
    max_age_h: float | None = None,
) -> list[xr.Dataset]:
    """Read background files; a damaged one is named in ``notes`` and left out.

    With ``ray_time``, only the files that :func:`match_rays` can give to one of these
    rays are read (chosen by the time in their names), so a folder of a year of hourly
    backgrounds costs one directory listing, not 8760 reads per unit.
    """
    selected: Sequence[str | os.PathLike] = paths
    if ray_time is not None and len(paths):
        named = []
        for p in paths:
            try:
                named.append((background_time(p), p))
            except CwprocError as exc:
                if notes is not None:
                    notes.append(f"background file not used: {exc}")
        named.sort(key=lambda item: item[0])
        times = np.array([t for t, _ in named], dtype="datetime64[ns]")
        wanted = np.unique(match_rays(ray_time, times, max_age_h))
        selected = [named[i][1] for i in wanted if i >= 0]
    out = []
    for p in selected:
        try:
            out.append(read_halo_background(p))
        except CwprocError as exc:
            if notes is not None:
                notes.append(f"background file not used: {exc}")
    return out


@dataclass(frozen=True)
class SnrCorrection:
    """What the SNR background correction did to the rays of a chunk or of a day.

    Attributes
    ----------
    method : str
        The ``snr_correction`` attribute of the corrected scans (``"None"``: the
        correction did not run on them: switched off, other scans, no background file).
    files : tuple of str
        The background files used (``background_files``).
    corrected : numpy.ndarray or None
        Per ray, True where a background file corrected the SNR; None when the
        correction did not run.
    summary : str
        The stage's one-line summary of the correction ('' when it did not run).
    """

    method: str
    files: tuple[str, ...]
    corrected: np.ndarray | None
    summary: str

    @staticmethod
    def of_day(parts: Sequence[SnrCorrection]) -> SnrCorrection | None:
        """The correction of a day from that of its chunks, in time order (None: none).

        One line for the day, as the whole-day run words it
        (:func:`cwproc.stages.snr_correction.correction_summary`): a single chunk's own
        summary, else the rays of all chunks counted again.
        """
        ran = [p for p in parts if p.corrected is not None]
        if not parts:
            return None
        files = tuple(sorted({f for p in parts for f in p.files}))
        if not ran:
            return SnrCorrection(parts[0].method, files, None, "")
        if len(ran) == 1:
            return dataclasses.replace(ran[0], method=parts[0].method, files=files)
        done = np.concatenate([p.corrected for p in ran])
        summary = correction_summary(done, list(files), np.where(done, 0, -1))
        return SnrCorrection(parts[0].method, files, done, summary)


def snr_corrected_scans(
    scans: xr.Dataset,
    unit: ProductUnit,
    config: Config,
    notes: list[str] | None = None,
    files: list[Path] | None = None,
) -> tuple[xr.Dataset, SnrCorrection]:
    """:func:`correct_background` with the summary line returned in the record, not noted.

    The other notes (a damaged or too short background file) go to ``notes``; the
    caller writes the summary of the day once (:meth:`SnrCorrection.of_day`).
    """
    own: list[str] = []
    out = correct_background(scans, unit, config, own, files)
    ran = "background_time" in out.variables and out is not scans
    if notes is not None:
        notes.extend(own[:-1] if ran else own)  # correct_snr writes its summary last
    record = SnrCorrection(
        method=str(out.attrs.get("snr_correction")),
        files=tuple(out.attrs.get("background_files", [])),
        corrected=~np.isnat(out["background_time"].values) if ran else None,
        summary=own[-1] if ran else "",
    )
    return out, record


def correct_background(
    scans: xr.Dataset,
    unit: ProductUnit,
    config: Config,
    notes: list[str] | None = None,
    files: list[Path] | None = None,
) -> xr.Dataset:
    """Stream Line scans with the SNR corrected by the background files (stage ``background``).

    Background files (``*Background_*.txt``) are looked for in ``[background] folder``,
    else beside each ``.hpl`` file of the unit; each ray takes the latest one measured
    at most ``max_age_h`` before it (Manninen et al. (2016); Vakkari et al. (2019)).
    Other scans, a switched-off correction or no background file: ``scans`` unchanged.
    A damaged background file is named in ``notes`` and the others are used. ``files``:
    :func:`find_background_files` of the unit when the caller holds them (a streamed
    day looks once, not once per chunk).
    """
    opts = config.background
    if not opts.enabled or "snr" not in scans:
        return scans
    if str(scans.attrs.get("instrument_kind", "")).lower() != "streamline":
        return scans
    if files is None:
        files = find_background_files((i.path for i in unit.inputs), opts.folder or None)
    if not files:
        if opts.folder and notes is not None:  # a configured folder: say why nothing is used
            notes.append(missing_folder_note(opts.folder))
        return scans
    return correct_snr(
        scans,
        read_backgrounds(files, notes, ray_time=scans["time"].values, max_age_h=opts.max_age_h),
        max_age_h=opts.max_age_h,
        min_range_m=opts.min_range_m,
        notes=notes,
    )
