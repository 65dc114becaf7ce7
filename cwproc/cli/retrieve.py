"""``cwproc retrieve``: wind and turbulence products from instrument files."""

from __future__ import annotations

import sys

import click

from cwproc.cli._common import (
    collapsed_notes,
    inputs_or_exit,
    load_config_or_fail,
    output_dir_or_exit,
    product_command,
    replaced_note,
    report_failure,
    run_outcome,
)


@product_command("retrieve", "Directory for the NetCDF products (created if missing).")
def retrieve(inputs: tuple[str, ...], outdir: str, config: str | None, quiet: bool) -> None:
    """Wind profile and turbulence products from lidar or sonic FILES (or directories).

    \b
    The format of each file is recognised from its content. Scan files (Stream Line
    .hpl, cwproc scan NetCDF) of one instrument and UTC day make one unit, written as
    <unit>_wind.nc and <unit>_turbulence.nc; ZephIR/WindCube exports give <name>_wind.nc;
    sonic logs give <name>_sf.nc. Exit status 0 when every input was processed, 1
    otherwise, with one line per failed input naming the file, the line and the problem.
    A note says what each file held; files in a row that held the same get one note.
    A product already in the output directory is replaced, with a note naming it; a
    product whose every value would be missing is not written, with a note saying why.
    A file of another instrument than the configuration's (-c zephir300 on .hpl files)
    is a failure. The configuration and the output directory are checked first.
    """
    cfg = load_config_or_fail(config)  # before the heavy imports: a typo is told at once
    output_dir_or_exit(outdir)
    from cwproc import progress
    from cwproc.pipeline import retrieve_files

    found = inputs_or_exit(inputs, cfg, quiet)
    files = found.files
    with progress.reporting(progress.shown_on(quiet=quiet)):
        report = retrieve_files(files, outdir, cfg)
    for line in report.failures:
        report_failure(line)
    if not quiet:
        for line in collapsed_notes(report.notes, [str(f) for f in files]):
            click.echo(f"note: {line}", err=True)
        if report.replaced:
            click.echo(f"note: {replaced_note(report.replaced)}", err=True)
        for path in report.written:
            click.echo(f"wrote {path}")
    summary, status = run_outcome(found, len(report.written), report.failures)
    if not quiet:
        click.echo(summary)
    sys.exit(status)
