"""``cwproc info``: what each file is (format, instrument, geometry, time span).

The descriptions are built in :mod:`cwproc.cli.describe`, imported when the command
runs (numpy, xarray and the readers), so that ``cwproc info --help`` starts fast.
"""

from __future__ import annotations

import sys

import click

from cwproc.cli._common import config_option, load_config_or_fail, report_failure
from cwproc.errors import CwprocError


@click.command("info")
@click.argument("files", nargs=-1, required=True, metavar="FILES...")
@config_option()
def info_command(files: tuple[str, ...], config: str | None) -> None:
    """What each of FILES is: format, instrument, rays, gates, time span, scans.

    \b
    Scan files (.hpl, scan NetCDF): system id, scan type, rays, gates and gate length,
    time span, elevation(s), azimuth coverage, number of 360-degree scans.
    Stream Line background files (Background_DDMMYY-HHMMSS.txt): time, gates, layout.
    Other formats (wind records, sonic): dimensions, time span and variables.
    -c reads the files with the reader options of a configuration ([reader.<format>]
    tables: a Gill log's start time and rate, a logger's UTC offset), as retrieve does.
    A file that cannot be read gives one line "error: <file>:<line>: <problem>" on
    stderr; the others are still listed. Exit status 1 when any file failed.
    """
    cfg = load_config_or_fail(config) if config is not None else None
    from cwproc.cli.describe import describe_file  # after the configuration: errors first

    failures = 0
    listed = 0
    for name in files:
        try:
            lines = describe_file(name, cfg)
        except CwprocError as exc:
            report_failure(str(exc))
            failures += 1
            continue
        except Exception as exc:  # a reader bug must not hide the other files
            report_failure(f"{name}: internal error while reading: {type(exc).__name__}: {exc}")
            failures += 1
            continue
        if listed:
            click.echo("")
        click.echo("\n".join(lines))
        listed += 1
    sys.exit(1 if failures else 0)
