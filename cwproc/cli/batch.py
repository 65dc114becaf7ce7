"""``cwproc batch``: incremental, locked, idempotent runs over an archive (cron)."""

from __future__ import annotations

import datetime as _dt
import logging
import re
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import click

from cwproc.cli._common import (
    collapsed_notes,
    config_option,
    load_config_or_fail,
    noted_files,
    output_dir_or_exit,
    report_failure,
)
from cwproc.errors import CwprocError

if TYPE_CHECKING:  # imported when the command runs: batch --help stays light
    from cwproc.batch import BatchReport, UnitOutcome

_LOG_FORMAT = "%(asctime)s %(levelname)s %(message)s"


@contextmanager
def batch_logging(log_file: str | None, verbose: bool) -> Iterator[None]:
    """Send the ``cwproc.batch`` log lines to ``log_file`` and, with ``verbose``, stderr."""
    logger = logging.getLogger("cwproc.batch")
    handlers: list[logging.Handler] = []
    if log_file:
        try:
            Path(log_file).parent.mkdir(parents=True, exist_ok=True)
            handler: logging.Handler = logging.FileHandler(log_file, encoding="utf-8")
        except OSError as exc:
            raise click.UsageError(f"--log-file {log_file}: {exc.strerror or exc}") from None
        handler.setLevel(logging.DEBUG if verbose else logging.INFO)
        handlers.append(handler)
    if verbose:
        handler = logging.StreamHandler(sys.stderr)
        handler.setLevel(logging.DEBUG)
        handlers.append(handler)
    formatter = logging.Formatter(_LOG_FORMAT, datefmt="%Y-%m-%dT%H:%M:%SZ")
    formatter.converter = time.gmtime  # UTC, as the Z says
    for handler in handlers:
        handler.setFormatter(formatter)
        logger.addHandler(handler)
    old_level, old_propagate = logger.level, logger.propagate
    logger.setLevel(logging.DEBUG)
    logger.propagate = False
    try:
        yield
    finally:
        for handler in handlers:
            logger.removeHandler(handler)
            handler.close()
        logger.setLevel(old_level)
        logger.propagate = old_propagate


class _Progress:
    """Units done, on a bar of :mod:`cwproc.progress` (shown only where it is turned on:
    a terminal, without -q or -v)."""

    def __init__(self) -> None:
        self._open = ExitStack()
        self.bar: Any = None

    def start(self, n_units: int) -> None:
        """The plan is made: ``n_units`` units to process."""
        from cwproc import progress

        if n_units > 0 and self.bar is None:
            self.bar = self._open.enter_context(
                progress.bar(desc="units", total=n_units, unit="unit")
            )

    def advance(self, _outcome: UnitOutcome) -> None:
        """One unit is done."""
        if self.bar is not None:
            self.bar.update(1)

    def finish(self) -> None:
        """Close the bar (the run ended, or was stopped)."""
        self._open.close()
        self.bar = None


def _terminate(signum: int, _frame: Any) -> None:
    """SIGTERM (systemctl stop, kill): unwind so the cluster is closed and the lock freed.

    The ledger already holds every finished unit; the unit in flight is redone next run.
    """
    raise SystemExit(128 + signum)


def summary_lines(report: BatchReport, verbose: bool) -> list[str]:
    """The human summary printed at the end of a run.

    It ends with the count of the ``error:`` lines printed (unlisted folders, refused
    files, failed units, nothing readable): the exit status is 1 exactly when that count
    is not 0, the rule of every product command (issue 34.6).
    """
    from cwproc.batch import PRODUCT_FORMAT

    lines = []
    if verbose:
        lines += [f"unrecognised: {info.error or info.path}" for info in report.unrecognised]
    products = sum(info.format == PRODUCT_FORMAT for info in report.unrecognised)
    skipped = f" ({products} cwproc product(s), skipped)" if products else ""
    lines.append(
        f"{report.discovered} file(s): {len(report.unrecognised)} unrecognised{skipped}, "
        + (
            f"{len(report.other_format)} of other formats (the configuration reads "
            f"{report.pinned_format} only), "
            if report.other_format
            else ""
        )
        + f"{len(report.file_failures)} refused (unreadable or another instrument); "
        f"{report.units_total} unit(s): "
        f"{len(report.succeeded)} processed, {report.units_up_to_date} up to date, "
        f"{len(report.failed)} failed"
        + (f"; {report.files_too_new} file(s) too new (--min-age)" if report.files_too_new else "")
        + (
            f"; before --since: {report.files_before_since} file(s) not read, "
            f"{report.units_before_since} unit(s) skipped"
            if report.files_before_since or report.units_before_since
            else ""
        )
        + (
            f"; {len(report.listing_failures)} folder(s) could not be listed"
            if report.listing_failures
            else ""
        )
        + f"; {len(report.failure_lines())} failure(s)"
        + f" [{report.seconds:.1f} s]"
    )
    return lines


#: a Dask scheduler address cwproc accepts: a network address of a running cluster
_SCHEDULER = re.compile(
    r"(?:(tcp|tls)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9][A-Za-z0-9.-]*):(\d{1,5})"
)


def check_scheduler_address(value: str | None) -> str | None:
    """The ``--scheduler`` value if it names a reachable kind of cluster; else exit 2.

    Only ``tcp://host:port``, ``host:port`` and ``tls://host:port`` are accepted
    (``inproc://``, ``http://``, a bare word or an empty value are usage errors, not
    tracebacks or a silent serial run). ``tls://`` needs Dask's TLS configuration
    (``distributed.comm.tls.ca-file`` and the client certificate and key).
    """
    if value is None:
        return None
    m = _SCHEDULER.fullmatch(value.strip())
    if m is None or not 0 < int(m.group(3)) < 65536:
        raise click.BadParameter(
            f"{value!r} is not a Dask scheduler address; use tcp://host:port "
            "(or tls://host:port with Dask's TLS settings)",
            param_hint="'--scheduler'",
        )
    if m.group(1) == "tls":
        try:
            import dask
        except ImportError:
            return value.strip()  # the run then explains how to install dask
        if not dask.config.get("distributed.comm.tls.ca-file", None):
            raise click.BadParameter(
                "tls:// needs Dask's TLS settings (distributed.comm.tls.ca-file, "
                "distributed.comm.tls.client.cert and .key); see docs/cron.md",
                param_hint="'--scheduler'",
            )
    return value.strip()


@click.command("batch")
@click.argument("input_dir", type=click.Path(exists=True, file_okay=False))
@click.argument("output_dir", type=click.Path(file_okay=False))
@config_option()
@click.option(
    "--since",
    type=click.DateTime(formats=["%Y-%m-%d"]),
    default=None,
    metavar="YYYY-MM-DD",
    help="Only units whose data begin on or after this UTC day (older files are not read).",
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Run units in N worker processes on this machine (a process pool).",
)
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    callback=lambda ctx, param, value: check_scheduler_address(value),
    help="Run on an existing Dask cluster: tcp://host:port, or tls://host:port with "
    "Dask's TLS settings (see docs/cron.md).",
)
@click.option(
    "--pattern",
    "patterns",
    multiple=True,
    metavar="GLOB",
    help="Consider only files matching GLOB (file name, or end of the path below "
    "INPUT_DIR); repeatable. Default: every file.",
)
@click.option(
    "--min-age",
    "min_age_s",
    type=click.FloatRange(min=0),
    default=0.0,
    show_default=True,
    metavar="SECONDS",
    help="Leave files modified less than SECONDS ago (still being written) for a later run.",
)
@click.option(
    "--wait",
    "wait_s",
    type=click.FloatRange(min=0),
    default=0.0,
    show_default=True,
    metavar="SECONDS",
    help="When another run holds OUTPUT_DIR, wait this long for it before giving up.",
)
@click.option(
    "--log-file",
    type=click.Path(dir_okay=False),
    default=None,
    help="Append one key=value line per unit (and per failed file) to this file.",
)
@click.option("-q", "--quiet", is_flag=True, help="Print only failures.")
@click.option("-v", "--verbose", is_flag=True, help="Log every unit and list unrecognised files.")
def batch_command(
    input_dir: str,
    output_dir: str,
    config: str | None,
    since: _dt.datetime | None,
    workers: int | None,
    scheduler: str | None,
    patterns: tuple[str, ...],
    min_age_s: float,
    wait_s: float,
    log_file: str | None,
    quiet: bool,
    verbose: bool,
) -> None:
    """Process every new or changed input under INPUT_DIR into OUTPUT_DIR.

    \b
    Inputs are recognised by content anywhere under INPUT_DIR and grouped into product
    units as `cwproc retrieve` does (scan files: one unit per instrument and UTC day).
    A ledger in OUTPUT_DIR/.cwproc/ remembers each unit's input checksums and the
    configuration: units already done are skipped, failed ones are retried next run.
    A lock (OUTPUT_DIR/.cwproc/lock) keeps two runs off the same OUTPUT_DIR.
    Exit status: 0 all done, 1 some input or unit failed, 2 usage error,
    75 another run holds the lock.
    """
    if workers is not None and scheduler:
        raise click.UsageError("give --workers or --scheduler, not both")
    if quiet and verbose:
        raise click.UsageError("give --quiet or --verbose, not both")
    cfg = load_config_or_fail(config)  # before the heavy imports: a typo is told at once
    output_dir_or_exit(output_dir)
    from cwproc import progress
    from cwproc.batch import EXIT_LOCKED, LockBusyError, close_client, run_batch

    client = _client_or_exit(workers, scheduler)
    units = _Progress()
    previous_sigterm = signal.signal(signal.SIGTERM, _terminate)
    try:
        with (
            batch_logging(log_file, verbose),
            progress.reporting(progress.shown_on(quiet=quiet or verbose)),
        ):
            report = run_batch(
                input_dir,
                output_dir,
                cfg,
                patterns=patterns or ("*",),
                since=since.date() if since else None,
                min_age_s=min_age_s,
                client=client,
                wait_s=wait_s,
                on_plan=units.start,
                on_unit=units.advance,
            )
    except LockBusyError as exc:
        click.echo(str(exc), err=True)
        sys.exit(EXIT_LOCKED)
    except CwprocError as exc:
        report_failure(str(exc))
        sys.exit(1)
    finally:
        signal.signal(signal.SIGTERM, previous_sigterm)
        units.finish()
        if client is not None:
            close_client(client)
    _report_and_exit(report, quiet, verbose)


def _client_or_exit(workers: int | None, scheduler: str | None) -> Any:
    """The executor of ``--workers`` (a local process pool) or ``--scheduler`` (a Dask
    client), None for neither; a scheduler that cannot be used exits with status 2."""
    from cwproc.batch import DaskNotInstalledError, dask_client, local_pool

    if workers is not None and not scheduler:
        return local_pool(workers)
    if not scheduler:
        return None
    try:
        return dask_client(scheduler=scheduler)
    except (DaskNotInstalledError, CwprocError) as exc:
        report_failure(str(exc))
        sys.exit(2)


def _report_and_exit(report: BatchReport, quiet: bool, verbose: bool) -> NoReturn:
    """Print the failures, notes and summary of a run; exit 0 when all went well, else 1."""
    from cwproc.pipeline import EXIT_FAILED, EXIT_OK

    if report.stale_lock and not quiet:
        click.echo(f"took over the lock of a run that ended abnormally ({report.stale_lock})")
    for line in report.failure_lines():
        report_failure(line)
    if not quiet:
        notes = report.notes()  # worded as cwproc retrieve words them
        for line in collapsed_notes(notes, noted_files(notes)):
            click.echo(f"note: {line}", err=True)
        for line in summary_lines(report, verbose):
            click.echo(line)
    sys.exit(EXIT_OK if report.ok else EXIT_FAILED)
