"""Helpers shared by the click commands: config loading and one-line error reports."""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from cwproc.config import Config, PresetAliasWarning, load_config, preset_names
from cwproc.errors import CwprocError

if TYPE_CHECKING:
    from cwproc.pipeline.file_search import Inputs


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


def with_product_options(
    cfg: Config, *, l1: bool, cross: str | None, layout: str | None, qc_report: bool
) -> Config:
    """``cfg`` with the product options of the command line (``--l1``, ``--cross``,
    ``--layout``, ``--qc-report``) over its ``[doppler_lidar]`` and ``[output]`` tables.

    ``--cross`` and ``--layout cloudnet`` need the L1 product and turn it on. A cross
    folder that is not a folder is a usage error (exit 2) naming it.
    """
    if cross is not None and not Path(cross).is_dir():
        raise click.UsageError(f"--cross {cross}: not a folder")
    dl: dict[str, object] = {}
    out: dict[str, object] = {}
    if l1 or cross is not None or layout == "cloudnet":
        dl["enabled"] = True
    if cross is not None:
        dl["cross_folder"] = str(cross)
    if layout is not None:
        out["layout"] = layout
    if qc_report:
        out["qc_report"] = True
    if not dl and not out:
        return cfg
    try:
        return cfg.replace(doppler_lidar=dl, output=out)
    except CwprocError as exc:
        raise click.UsageError(str(exc)) from None


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
    """Exit 2 with one line when the dependency ``module`` is missing from this install.

    Called before any computing, so that a missing module never costs a run. matplotlib
    and tqdm are base dependencies of cwproc: a missing one means an install that did
    not finish or a package removed since, mended by installing cwproc again from the
    clone it came from (``pip install .`` at the top of the clone). ``extra`` names
    the optional-dependency group that also lists ``module`` (kept for old scripts).
    """
    import importlib.util

    if importlib.util.find_spec(module) is None:
        usage_error(
            f"{what} needs {module}, which is missing from this Python environment; "
            "install cwproc again from the top of its clone: pip install ."
        )


def output_dir_or_exit(outdir: str) -> None:
    """Create ``outdir`` if missing and check that a file can be written in it.

    Called before any input is read: a read-only, misspelt or full product directory
    stops the run at once (exit 2, one line naming the directory and the problem),
    not after all the work. The check writes and removes a hidden empty file, which
    also catches a read-only filesystem and the superuser's read-only mounts.
    """
    import tempfile

    path = Path(outdir)
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".cwproc-check-"):
            pass
    except OSError as exc:
        usage_error(f"-o {outdir}: cannot write products there: {exc.strerror or exc}")


def check_index(value: int | None, size: int, option: str, what: str) -> None:
    """Exit 2 when an index option lies outside ``0 .. size-1``, naming the valid range."""
    if value is None:
        return
    if size == 0:
        usage_error(f"{option} {value}: there are no {what} to choose from")
    if not 0 <= value < size:
        usage_error(f"{option} {value} is out of range: the {what} are 0 .. {size - 1}")


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
    from cwproc.pipeline.file_search import expand_inputs  # not at import: --help stays light

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


def run_outcome(found: Inputs, n_written: int, failures: list[str]) -> tuple[str, int]:
    """The summary line of a product command and its exit status, by one rule (34.6).

    Every failure line printed is counted, those of inputs named on the command line
    that the configuration does not read (``found.mismatched``) included, and the exit
    status is 1 exactly when that count is not 0: the summary and the status never
    disagree (a file refused before the run said "0 failure(s)" and exited 1).

    Returns
    -------
    (str, int)
        ``"N input(s), M product(s) written, K failure(s)..."`` and 0 or 1.
    """
    n_failed = len(failures) + len(found.mismatched)
    n_inputs = len(found.files) + len(found.mismatched)
    line = (
        f"{n_inputs} input(s), {n_written} product(s) written, "
        f"{n_failed} failure(s){found.skipped_text()}"
    )
    return line, (1 if n_failed else 0)


#: files in a row whose note lines say the same, from which ``cwproc retrieve`` and
#: ``cwproc batch`` print one line for them all (a day of 1920 scan files would otherwise
#: print 1920 alike lines)
ALIKE_FILES_MIN = 4


def collapsed_notes(notes: list[str], paths: list[str]) -> list[str]:
    """``notes`` with each run of at least :data:`ALIKE_FILES_MIN` consecutive lines that
    say the same of different input files (``"<path>: <text>"``, ``path`` one of
    ``paths``) made one line: ``"<n> files <first> .. <last>: <text>"``.

    Every other line is kept as it is, in its place; a file whose line differs (stares
    among the VAD scans, rays not used) ends the run and keeps its own line.
    """
    known = {str(p) for p in paths}

    def split(line: str) -> tuple[str, str] | None:
        at = line.find(": ")
        while at >= 0:  # the shortest path the line begins with (one set look-up a ": ")
            if line[:at] in known:
                return line[:at], line[at + 2 :]
            at = line.find(": ", at + 1)
        return None

    out: list[str] = []
    run: list[tuple[str, str]] = []

    def flush() -> None:
        if len(run) >= ALIKE_FILES_MIN:
            out.append(f"{len(run)} files {run[0][0]} .. {run[-1][0]}: {run[0][1]}")
        else:
            out.extend(f"{path}: {text}" for path, text in run)
        run.clear()

    for line in notes:
        parts = split(line)
        if run and (parts is None or parts[1] != run[-1][1]):
            flush()
        if parts is None:
            out.append(line)
        else:
            run.append(parts)
    flush()
    return out


def noted_files(notes: list[str]) -> list[str]:
    """The files that lines of ``notes`` begin with (``"<path>: ..."``, ``path`` an
    existing file): the ``paths`` of :func:`collapsed_notes` where the caller has no
    list of its inputs (``cwproc batch``, whose notes come from its units' workers)."""
    heads = {line.split(": ", 1)[0] for line in notes if ": " in line}
    return [head for head in heads if os.path.isfile(head)]


#: products named in full by :func:`replaced_note` (the others are counted)
REPLACED_SHOWN = 3


def replaced_note(paths: list[Path]) -> str:
    """One note for the products that replaced the files of an earlier run.

    A second run into the same ``-o`` replaces its products (the new ones carry the
    new run's provenance); the note says so, naming the first few.
    """
    names = ", ".join(str(p) for p in paths[:REPLACED_SHOWN])
    more = f" and {len(paths) - REPLACED_SHOWN} more" if len(paths) > REPLACED_SHOWN else ""
    return f"{len(paths)} product(s) of an earlier run replaced: {names}{more}"
