"""``cwproc sf-type``: structure-function types of sonic-anemometer data per UTC day.

Gladkikh et al. (2014): every input is read on its own (a damaged file fails alone,
with one line naming the file, the line and the problem), the samples are grouped by
file format and UTC day, the chain of :func:`cwproc.pipeline.run_unit`
(:func:`cwproc.stages.sonic_sf.structure_function_types`) types every 10-min window,
one NetCDF product is written per day, and the summary tables (Table 2: type
occurrence; Tables 3-5: parameter means and medians) are printed and written as CSV.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from cwproc.cli._common import (
    inputs_or_exit,
    load_config_or_fail,
    output_dir_or_exit,
    product_command,
    replaced_note,
    report_failure,
    run_outcome,
)


@product_command(
    "sf-type", "Directory for the NetCDF products and summary CSV files (created if missing)."
)
def sf_type_command(inputs: tuple[str, ...], outdir: str, config: str | None, quiet: bool) -> None:
    """Structure-function types of sonic FILES (TOA5, TOB1, GHG, Gill, Meteo-2).

    \b
    Gladkikh et al. (2014): per 10-min window and wind component (longitudinal,
    transverse, vertical) the normalised structure function is typed 1 (line),
    2 (parabola) or 3 (parabola then line) in lg-lg axes. Writes one product per
    file format, station (from the file's header, else its folder) and UTC day,
    <format>_<station>_<YYYYMMDD>_sf.nc (loggers sharing a station name but not
    their serial, table, program or folder are kept apart:
    <format>_<station>-<serial>_<YYYYMMDD>_sf.nc, with a note), plus
    sf_type_occurrence.csv (Table 2) and sf_parameters.csv (Tables 3-5), and prints
    both tables. Exit status 0 when every input was processed, 1 otherwise, with one
    line per failed input naming the file, the line and the problem. Products and
    tables already in the output directory are replaced (a note names the products).
    """
    cfg = load_config_or_fail(config)  # before the heavy imports: a typo is told at once
    output_dir_or_exit(outdir)
    import pandas as pd  # here, not at import: --help stays light

    from cwproc import progress
    from cwproc.io.netcdf import write_bytes_atomic
    from cwproc.pipeline import retrieve_files, sf_summary_tables

    found = inputs_or_exit(inputs, cfg, quiet)
    files = found.files
    with progress.reporting(progress.shown_on(quiet=quiet)):
        report = retrieve_files(files, outdir, cfg, kinds={"sonic"}, keep_products=True)
    written, failures = report.written, report.failures
    products = [ds for _, name, ds in report.products if name == "sf"]
    for line in failures:
        report_failure(line)
    if products:
        occurrence, stats = sf_summary_tables(products)
        out = Path(outdir)
        tables = {
            out / "sf_type_occurrence.csv": occurrence.to_csv(float_format="%.2f"),
            out / "sf_parameters.csv": stats.to_csv(index=False, float_format="%.4f"),
        }
        for path, text in tables.items():  # whole or not at all, as the products
            try:
                write_bytes_atomic(path, text.encode("utf-8"))
            except OSError as exc:
                raise click.ClickException(
                    f"{path}: cannot write the table: {exc.strerror or exc}"
                ) from None
        if not quiet:
            with pd.option_context("display.width", 120, "display.max_rows", 200):
                click.echo(
                    "Type occurrence (% of observed windows), Gladkikh et al. (2014) Table 2"
                )
                click.echo(occurrence.round(2).to_string())
                click.echo("\nParameter means and medians, Tables 3-5")
                click.echo(stats[stats["count"] > 0].round(4).to_string(index=False))
    if not quiet:
        if report.replaced:
            click.echo(f"note: {replaced_note(report.replaced)}", err=True)
        for path in written:
            click.echo(f"wrote {path}")
    summary, status = run_outcome(found, len(written), failures)
    if not quiet:
        click.echo(summary)
    sys.exit(status)
