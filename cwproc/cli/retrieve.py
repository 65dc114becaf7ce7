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
    with_product_options,
)


@product_command("retrieve", "Directory for the NetCDF products (created if missing).")
@click.option(
    "--l1",
    is_flag=True,
    help="Also write the Level-1 stare product <unit>_doppler_lidar.nc (beta, "
    "depolarisation, screened velocity; [doppler_lidar] enabled).",
)
@click.option(
    "--cross",
    "cross",
    type=click.Path(file_okay=False),
    default=None,
    help="Folder of the cross-polarised .hpl files (and their Background_*.txt) for the "
    "depolarisation ratio; implies --l1.",
)
@click.option(
    "--layout",
    type=click.Choice(["cwproc", "cloudnet"]),
    default=None,
    help="cloudnet: also write <unit>_doppler-lidar.nc and <unit>_doppler-lidar-wind.nc "
    "in the variable names cloudnetpy reads (implies --l1). Default: [output] layout.",
)
@click.option(
    "--qc-report",
    is_flag=True,
    help="Write <product>.qc.json beside every product: coverage, flagged fractions by "
    "bit, CF/ACDD check, inputs refused.",
)
def retrieve_command(
    inputs: tuple[str, ...],
    outdir: str,
    config: str | None,
    quiet: bool,
    l1: bool,
    cross: str | None,
    layout: str | None,
    qc_report: bool,
) -> None:
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
    cfg = with_product_options(cfg, l1=l1, cross=cross, layout=layout, qc_report=qc_report)
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
        for path in report.quality_reports:
            click.echo(f"wrote {path}")
    summary, status = run_outcome(found, len(report.written), report.failures)
    if not quiet:
        click.echo(summary)
    sys.exit(status)
