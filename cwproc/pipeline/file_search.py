"""The inputs of a run: files named, folders searched, and what is skipped and why."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.io import Format, detect_format, is_cwproc_product
from cwproc.pipeline.input_checks import format_mismatch, no_input_of_format, other_formats_note


@dataclass
class Inputs:
    """The files a command will process, and those it skips (with the reason)."""

    files: list[Path] = field(default_factory=list)
    #: files of no format cwproc reads, found in directories
    unknown: list[Path] = field(default_factory=list)
    #: cwproc's own products (NetCDF written by cwproc), found anywhere
    products: list[Path] = field(default_factory=list)
    #: files in directories of a format the configuration does not read
    other_format: list[Path] = field(default_factory=list)
    #: files named on the command line of a format the configuration does not read
    mismatched: list[str] = field(default_factory=list)
    #: the format of each file of ``other_format``
    other_formats: list[str] = field(default_factory=list)
    #: the format the configuration reads ("auto": any)
    pinned: str = "auto"

    @property
    def skipped_notes(self) -> list[str]:
        """One note for all the files of ``other_format`` (none when there is none)."""
        if not self.other_format:
            return []
        paths = [str(p) for p in self.other_format]
        return [other_formats_note(paths, self.other_formats, self.pinned)]

    def skipped_text(self) -> str:
        """``", 3 file(s) of no known format skipped, 2 cwproc product(s) skipped"``."""
        text = ""
        if self.unknown:
            text += f", {len(self.unknown)} file(s) of no known format skipped"
        if self.products:
            text += f", {len(self.products)} cwproc product(s) skipped (not instrument files)"
        if self.other_format:
            text += (
                f", {len(self.other_format)} file(s) of other formats skipped "
                f"(the configuration reads {self.pinned} only)"
            )
        return text

    def nothing_readable(self) -> str:
        """Why nothing can be done when every file found is of another format ('' else).

        ``cwproc retrieve`` and ``cwproc batch`` fail with this line (exit status 1): a
        configuration that reads none of the inputs is a mistake, not an empty day.
        """
        if self.files or self.mismatched or not self.other_format:
            return ""
        return no_input_of_format(len(self.other_format), self.pinned)


def expand_inputs(inputs: tuple[str, ...], config: Config) -> Inputs:
    """Files to process and files skipped.

    Files named on the command line are processed (an unreadable or unknown one is
    reported as a failure). Directories are searched recursively; there, files of no
    format cwproc reads (notes, trajectory files, ...) are skipped and counted.
    cwproc's own products are skipped wherever they are (an output folder inside the
    input folder, a product named by a wildcard), so that a second run over the same
    folder reads the same inputs as the first. When the configuration reads one format
    only (``[instrument] format``, e.g. ``hpl`` for the Stream Line preset), files of
    other formats are skipped in directories (one line for them all in ``skipped_notes``,
    as ``cwproc batch`` words it, :func:`cwproc.pipeline.other_formats_note`) and reported
    in ``mismatched`` when named.
    """
    found = Inputs(pinned=config.instrument.format)
    for item in inputs:
        p = Path(item)
        if not p.is_dir():
            if is_cwproc_product(p):
                found.products.append(p)
                continue
            fmt = _format_or_none(p)
            mismatch = format_mismatch(p, fmt, config) if fmt is not None else ""
            if mismatch:
                found.mismatched.append(mismatch)
                continue
            found.files.append(p)
            continue
        for q in sorted(q for q in p.rglob("*") if q.is_file() and not _hidden(q, p)):
            try:
                fmt = detect_format(q)
            except CwprocError:
                found.unknown.append(q)
                continue
            if fmt is Format.SCAN_NETCDF and is_cwproc_product(q):
                found.products.append(q)
                continue
            mismatch = format_mismatch(q, fmt, config)
            if mismatch:
                found.other_format.append(q)
                found.other_formats.append(fmt.value)
                continue
            found.files.append(q)
    return found


def _format_or_none(path: Path) -> Format | None:
    try:
        return detect_format(path)
    except CwprocError:
        return None


def _hidden(path: Path, root: Path) -> bool:
    """A file whose name or any folder below ``root`` starts with a dot (e.g. .cwproc/)."""
    return any(part.startswith(".") for part in path.relative_to(root).parts)
