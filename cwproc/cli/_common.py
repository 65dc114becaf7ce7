"""Helpers shared by the click commands: config loading and one-line error reports."""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import click

from cwproc.config import Config, PresetAliasWarning, load_config, preset_names
from cwproc.errors import CwprocError


def config_option(default: str | None = None) -> Callable[[Any], Any]:
    """The ``-c/--config`` option: a TOML file or the name of a preset."""
    return click.option(
        "-c",
        "--config",
        "config",
        default=default,
        show_default=default is not None,
        metavar="FILE|PRESET",
        help=(f"Configuration: a TOML file or a preset name ({', '.join(preset_names())})."),
    )


def load_config_or_fail(value: str | None) -> Config:
    """Load the configuration; a bad one is a usage error (exit 2) with one clear line."""
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PresetAliasWarning)
            cfg = load_config(value)
    except CwprocError as exc:
        raise click.UsageError(str(exc)) from None
    for w in caught:
        if issubclass(w.category, PresetAliasWarning):
            click.echo(f"warning: {w.message}", err=True)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return cfg


def report_failure(message: str) -> None:
    """Print one failure line on stderr (``error: <file>:<line>: <problem>``)."""
    click.echo(f"error: {message}", err=True)


def fail(message: str, code: int = 1) -> None:
    """Print one failure line and exit with ``code``."""
    report_failure(message)
    sys.exit(code)


def usage_error(message: str) -> None:
    """A bad command-line argument: one line on stderr, exit status 2, before any work."""
    fail(message, code=2)


def require_extra(module: str, extra: str, what: str) -> None:
    """Exit 2 with one line when the optional dependency ``module`` is not installed.

    Called before any computing, so that a missing extra never costs a run.
    """
    import importlib.util

    if importlib.util.find_spec(module) is None:
        usage_error(
            f"{what} needs {module}, which is not installed: install the {extra} extra, "
            f'pip install "cwproc[{extra}]"'
        )


def check_index(value: int | None, size: int, option: str, what: str) -> None:
    """Exit 2 when an index option lies outside ``0 .. size-1``, naming the valid range."""
    if value is None:
        return
    if size == 0:
        usage_error(f"{option} {value}: there are no {what} to choose from")
    if not 0 <= value < size:
        usage_error(f"{option} {value} is out of range: the {what} are 0 .. {size - 1}")


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
    #: the format the configuration reads ("auto": any)
    pinned: str = "auto"

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


def expand_inputs(inputs: tuple[str, ...], pinned: str = "auto") -> Inputs:
    """Files to process and files skipped.

    Files named on the command line are processed (an unreadable or unknown one is
    reported as a failure). Directories are searched recursively; there, files of no
    format cwproc reads (notes, trajectory files, ...) are skipped and counted.
    cwproc's own products are skipped wherever they are (an output folder inside the
    input folder, a product named by a wildcard), so that a second run over the same
    folder reads the same inputs as the first. When the configuration reads one format
    only (``pinned``, e.g. ``hpl`` for the Stream Line preset), files of other formats
    are skipped in directories and reported in ``mismatched`` when named.
    """
    from cwproc.io import Format, detect_format, is_cwproc_product

    found = Inputs(pinned=pinned)
    for item in inputs:
        p = Path(item)
        if not p.is_dir():
            if is_cwproc_product(p):
                found.products.append(p)
                continue
            fmt = _format_or_none(p)
            if pinned != "auto" and fmt is not None and fmt.value != pinned:
                found.mismatched.append(
                    f"{p}: a {fmt.value} file, but the configuration reads only {pinned}"
                )
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
            if pinned != "auto" and fmt.value != pinned:
                found.other_format.append(q)
                continue
            found.files.append(q)
    return found


def _format_or_none(path: Path):
    from cwproc.io import detect_format

    try:
        return detect_format(path)
    except CwprocError:
        return None


def _hidden(path: Path, root: Path) -> bool:
    """A file whose name or any folder below ``root`` starts with a dot (e.g. .cwproc/)."""
    return any(part.startswith(".") for part in path.relative_to(root).parts)
