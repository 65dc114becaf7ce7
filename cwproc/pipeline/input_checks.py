"""Whether a configuration reads an input: the format it pins, the instrument it describes.

The lines here name the file and both sides (its format or instrument, the
configuration's), for the failures and notes of ``cwproc retrieve`` and ``cwproc batch``.
"""

from __future__ import annotations

import os
from collections import Counter

from cwproc.config import Config
from cwproc.io import KIND, Format
from cwproc.pipeline.input_files import InputFile, held_or_identity


def format_mismatch(path: str | os.PathLike, fmt: Format, config: Config) -> str:
    """Why ``config`` does not read a file of format ``fmt`` ('' when it does).

    A configuration that pins ``[instrument] format`` (a preset for one instrument)
    reads files of that format only; ``cwproc retrieve`` and ``cwproc batch`` skip the
    others with this line, naming the file and the format. A Stream Line background
    file belongs to a configuration that reads ``.hpl`` files.
    """
    pinned = config.instrument.format
    if pinned == "auto" or fmt.value == pinned:
        return ""
    if fmt is Format.HALO_BACKGROUND and pinned == Format.HPL.value:
        return ""  # read with the .hpl files beside it (stage background), never refused
    return f"{os.fspath(path)}: a {fmt.value} file, but the configuration reads only {pinned}"


#: the kind of instrument of a format whose files come from one kind only
_FORMAT_KIND = {
    Format.HPL: "pulsed",
    Format.WINDCUBE_STA: "pulsed",
    Format.WINDCUBE_RTD: "pulsed",
    Format.ZEPHIR_CSV: "cw",
}


#: ``instrument_kind`` attribute of scans -> the kind of ``[instrument] kind``
_SCAN_KIND = {"streamline": "pulsed", "pulsed": "pulsed", "cw": "cw"}


#: a preset of each kind, named in the message
_PRESET_OF_KIND = {"pulsed": "streamline", "cw": "zephir300"}


def instrument_mismatch(item: InputFile, config: Config) -> str:
    """Why ``config`` describes another instrument than the one of ``item`` ('' if not).

    A lidar file (Stream Line ``.hpl``, WindCube: pulsed; ZephIR: cw; scan NetCDF: its
    ``instrument_kind``) read with a configuration of another ``[instrument] kind``
    (e.g. ``-c zephir300``, a cw lidar, on ``.hpl`` files) would be processed with the
    wrong probe volume and presets: it is a failure naming the file and both
    instruments. The defaults (no ``-c``) read every file, as do sonic logs under any
    configuration (their analysis uses no lidar setting).
    """
    if config.source == "<defaults>" or KIND.get(item.format) not in ("scan", "wind_record"):
        return ""
    attrs = getattr(held_or_identity(item), "attrs", {}) or {}
    declared = str(attrs.get("instrument_kind", "")).strip().lower()
    kind = _FORMAT_KIND.get(item.format) or _SCAN_KIND.get(declared)
    if kind is None or kind == config.instrument.kind:
        return ""
    made_by = str(attrs.get("instrument", "")) or item.format.value
    preset = _PRESET_OF_KIND.get(kind, "")
    return (
        f"{os.fspath(item.path)}: a file of a {kind} lidar ({made_by}), but configuration "
        f"{config.source} describes {config.instrument.name} ({config.instrument.kind}"
        f"{' lidar' if config.instrument.kind != 'sonic' else ''}); use a configuration "
        f"for its instrument{f' (e.g. -c {preset})' if preset else ''}"
    )


def other_formats_note(paths: list[str], formats: list[str], pinned: str) -> str:
    """One note for every file skipped because the configuration reads another format.

    ``"7 files of other instruments skipped (ghg, toa5 in sample_data/sonic; zephir_csv
    in sample_data/zephir): the configuration reads hpl only"``: the formats (with their
    count when more than one file) and the folders they were found in, in place of one
    line per file (:func:`format_mismatch` words a file named on the command line).
    """
    counts = Counter(formats)
    kinds = ", ".join(f"{n} {f}" if n > 1 else f for f, n in sorted(counts.items()))
    folders = sorted({os.path.dirname(os.fspath(p)) or "." for p in paths})
    shown = ", ".join(folders[:3]) + (f" and {len(folders) - 3} more" if len(folders) > 3 else "")
    return (
        f"{len(paths)} file{'s' if len(paths) != 1 else ''} of other instruments skipped "
        f"({kinds} in {shown}): "
        f"the configuration reads {pinned} only"
    )


def no_input_of_format(n_skipped: int, pinned: str) -> str:
    """The failure of a run whose every input is of a format the configuration does not read."""
    return (
        f"none of the inputs is a {pinned} file, the only format the configuration reads "
        f"({n_skipped} file(s) of other formats skipped); use a configuration for their "
        'instrument, or one with [instrument] format = "auto"'
    )
