"""``cwproc retrieve``: wind and turbulence products from instrument files."""

from __future__ import annotations

import sys

import click

from cwproc.cli._common import (
    config_option,
    expand_inputs,
    load_config_or_fail,
    report_failure,
)


@click.command("retrieve")
@click.argument("inputs", nargs=-1, required=True, metavar="FILES...")
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(file_okay=False),
    help="Directory for the NetCDF products (created if missing).",
)
@config_option()
@click.option("-q", "--quiet", is_flag=True, help="Print only failures.")
def retrieve(inputs: tuple[str, ...], outdir: str, config: str | None, quiet: bool) -> None:
    """Wind profile and turbulence products from lidar or sonic FILES (or directories).

    \b
    The format of each file is recognised from its content. Scan files (Stream Line
    .hpl, cwproc scan NetCDF) of one instrument and UTC day make one unit, written as
    <unit>_wind.nc and <unit>_turbulence.nc; ZephIR/WindCube exports give <name>_wind.nc;
    sonic logs give <name>_sf.nc. Exit status 0 when every input was processed, 1
    otherwise, with one line per failed input naming the file, the line and the problem.
    """
    from cwproc.pipeline import retrieve_files

    cfg = load_config_or_fail(config)
    found = expand_inputs(inputs, cfg.instrument.format)
    files = found.files
    for line in found.mismatched:
        report_failure(line)
    if not files:
        if found.mismatched:
            sys.exit(1)
        raise click.UsageError(f"no input files found{found.skipped_text()}")
    report = retrieve_files(files, outdir, cfg)
    for line in report.failures:
        report_failure(line)
    if not quiet:
        for line in report.notes:
            click.echo(f"note: {line}", err=True)
        for path in report.written:
            click.echo(f"wrote {path}")
        click.echo(
            f"{len(files)} input(s), {len(report.written)} product(s) written, "
            f"{len(report.failures)} failure(s){found.skipped_text()}"
        )
    sys.exit(0 if report.ok and not found.mismatched else 1)
