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
    #: one line per file of ``other_format``: the file and why it is skipped
    skipped_notes: list[str] = field(default_factory=list)
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

    def nothing_readable(self) -> str:
        """Why nothing can be done when every file found is of another format ('' else).

        ``cwproc retrieve`` and ``cwproc batch`` fail with this line (exit status 1): a
        configuration that reads none of the inputs is a mistake, not an empty day.
        """
        if self.files or self.mismatched or not self.other_format:
            return ""
        from cwproc.pipeline import no_input_of_format

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
    other formats are skipped in directories (one line each in ``skipped_notes``, as
    ``cwproc batch`` words them, :func:`cwproc.pipeline.format_mismatch`) and reported
    in ``mismatched`` when named.
    """
    from cwproc.io import Format, detect_format, is_cwproc_product
    from cwproc.pipeline import format_mismatch  # not at import: --help stays light

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
                found.skipped_notes.append(f"{mismatch}: skipped")
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


def product_command(name: str, outdir_help: str) -> Callable[[Any], Any]:
    """The arguments and options shared by the commands that make products from files.

    ``FILES...`` (files or directories), ``-o/--output`` (the product directory),
    ``-c/--config`` and ``-q/--quiet`` (``cwproc retrieve``, ``cwproc sf-type``).
    """

    def decorate(fn: Callable[..., Any]) -> Any:
        for option in reversed(
            (
                click.command(name),
                click.argument("inputs", nargs=-1, required=True, metavar="FILES..."),
                click.option(
                    "-o",
                    "--output",
                    "outdir",
                    required=True,
                    type=click.Path(file_okay=False),
                    help=outdir_help,
                ),
                config_option(),
                click.option("-q", "--quiet", is_flag=True, help="Print only failures."),
            )
        ):
            fn = option(fn)
        return fn

    return decorate


def inputs_or_exit(inputs: tuple[str, ...], config: Config, quiet: bool) -> Inputs:
    """The files to process; exits when there is none (after saying why).

    A file named on the command line of a format the configuration does not read is a
    failure line (exit status 1 at the end); files of other formats found in directories
    are named in notes (unless ``quiet``). When not one file is left: exit 1 when every
    file found is of another format (:meth:`Inputs.nothing_readable`, the line ``cwproc
    batch`` gives on the same folder), else a usage error (exit 2).
    """
    found = expand_inputs(inputs, config)
    for line in found.mismatched:
        report_failure(line)
    if not quiet:
        for line in found.skipped_notes:
            click.echo(f"note: {line}", err=True)
    if not found.files:
        nothing = found.nothing_readable()
        if nothing:
            fail(nothing)
        if found.mismatched:
            sys.exit(1)
        raise click.UsageError(f"no input files found{found.skipped_text()}")
    return found
