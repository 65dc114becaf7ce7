"""``cwproc sf-type``: structure-function types of sonic-anemometer data per UTC day.

Gladkikh et al. (2014): every input is read on its own (a damaged file fails alone,
with one line naming the file, the line and the problem), the samples are grouped by
file format and UTC day, the stage :func:`cwproc.stages.sonic_sf.structure_function_types`
types every 10-min window, one NetCDF product is written per day, and the summary
tables (Table 2: type occurrence; Tables 3-5: parameter means and medians) are printed
and written as CSV.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from pathlib import Path

import click
import numpy as np
import pandas as pd
import xarray as xr

from cwproc.cli._common import config_option, load_config_or_fail, report_failure
from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.io import KIND, detect_format
from cwproc.io.netcdf import site_attributes, write_product
from cwproc.metadata import GLADKIKH_2014
from cwproc.pipeline import InputFile, read_input
from cwproc.stages.sonic_sf import (
    parameter_statistics,
    structure_function_types,
    type_occurrence,
)

#: relative spread of the sampling rates of files that may be typed together
RATE_TOLERANCE = 0.01


def expand_sonic_inputs(inputs: Sequence[str]) -> list[Path]:
    """Files named on the command line, and the readable files found in directories.

    A named file is always processed (an unknown one is reported as a failure); inside
    a directory, files of no format cwproc reads (e.g. ``truth.json``) are skipped.
    """
    out: list[Path] = []
    for item in inputs:
        p = Path(item)
        if not p.is_dir():
            out.append(p)
            continue
        for q in sorted(q for q in p.rglob("*") if q.is_file() and not q.name.startswith(".")):
            try:
                detect_format(q)
            except CwprocError:
                continue
            out.append(q)
    return out


def split_by_day(item: InputFile) -> dict[str, xr.Dataset]:
    """The samples of one input grouped by UTC day (``YYYYMMDD`` keys)."""
    ds = item.dataset
    assert ds is not None
    days = ds["time"].values.astype("datetime64[D]")
    out = {}
    for day in np.unique(days):
        key = str(day).replace("-", "")
        out[key] = ds.isel(time=np.flatnonzero(days == day))
    return out


def day_dataset(parts: Sequence[xr.Dataset], label: str) -> xr.Dataset:
    """Concatenate the parts of one instrument-day in time order.

    Raises
    ------
    CwprocError
        The parts have sampling rates that differ by more than 1 %.
    """
    rates = np.array([float(p.attrs["sampling_rate_hz"]) for p in parts])
    if np.ptp(rates) > RATE_TOLERANCE * np.median(rates):
        listed = ", ".join(f"{r:g}" for r in rates)
        raise CwprocError(f"{label}: inputs have different sampling rates ({listed} Hz)")
    ds = parts[0] if len(parts) == 1 else xr.concat(parts, dim="time", combine_attrs="drop")
    ds = ds.sortby("time")
    ds.attrs = dict(parts[0].attrs)
    ds.attrs["sampling_rate_hz"] = float(np.median(rates))
    return ds


def type_day(ds: xr.Dataset, config: Config) -> xr.Dataset:
    """Run the stage with every parameter of the ``[sonic]`` section."""
    s = config.sonic
    return structure_function_types(
        ds,
        window_s=s.window_s,
        running_mean_s=s.running_mean_s,
        max_lag_fraction=s.max_lag_fraction,
        kd_threshold=s.kd_threshold,
        normalisation_lag_m=s.normalisation_lag_m,
        precedence_tolerance=s.precedence_tolerance,
        min_fit_points=s.min_fit_points,
        min_valid_fraction=s.min_valid_fraction,
        curvature_tolerance=s.curvature_tolerance,
    )


def run_sf_type(
    files: Sequence[str | os.PathLike], outdir: str | os.PathLike, config: Config
) -> tuple[list[Path], list[str], list[xr.Dataset]]:
    """Read, type and write; never stops at the first bad input.

    Returns
    -------
    written : list of Path
        Products.
    failures : list of str
        One line per failed input or day.
    products : list of xarray.Dataset
        The SF products (for the summary tables).
    """
    failures: list[str] = []
    groups: dict[tuple[str, str], list[InputFile]] = {}
    parts: dict[tuple[str, str], list[xr.Dataset]] = {}
    for path in files:
        try:
            item = read_input(path, config)
        except CwprocError as exc:
            failures.append(str(exc))
            continue
        if KIND[item.format] != "sonic":
            failures.append(f"{path}: not sonic-anemometer data ({item.format.value})")
            continue
        instrument = item.format.value
        for day, ds in split_by_day(item).items():
            groups.setdefault((instrument, day), []).append(item)
            parts.setdefault((instrument, day), []).append(ds)
    written: list[Path] = []
    products: list[xr.Dataset] = []
    for key in sorted(groups):
        instrument, day = key
        label = f"{instrument}_{day}"
        try:
            sf = type_day(day_dataset(parts[key], label), config)
            path = Path(outdir) / f"{label}_sf.nc"
            inputs = list(dict.fromkeys(i.path for i in groups[key]))
            extra = site_attributes(config.output)
            extra["instrument"] = str(parts[key][0].attrs.get("instrument", ""))
            written.append(
                write_product(
                    sf,
                    path,
                    title=f"cwproc structure-function types of sonic data: {label}",
                    summary=(
                        "Types (1 line, 2 parabola, 3 parabola then line in lg-lg axes) and "
                        "fitted coefficients of the normalised structure functions of the "
                        "longitudinal, transverse and vertical wind per 10-min window"
                    ),
                    inputs=inputs,
                    checksums={os.fspath(i.path): i.sha256 for i in groups[key]},
                    config_toml=config.to_toml(),
                    references=GLADKIKH_2014,
                    keywords="sonic anemometer, structure function, turbulence, surface layer",
                    extra_attrs=extra,
                    compression_level=config.output.compression_level,
                )
            )
            products.append(sf)
        except CwprocError as exc:
            failures.append(str(exc))
    return written, failures, products


def summary_tables(products: Sequence[xr.Dataset]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Table 2 and Tables 3-5 of Gladkikh et al. (2014) over all products."""
    keep = ["sf_type", "window_flag", "r_max", "sf_mu", "sf_a1", "sf_a2"]
    keep += ["sf_d1", "sf_d2", "sf_gamma"]
    joined = xr.concat([p[keep] for p in products], dim="window")
    return type_occurrence(joined), parameter_statistics(joined)


@click.command("sf-type")
@click.argument("inputs", nargs=-1, required=True, metavar="FILES...")
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(file_okay=False),
    help="Directory for the NetCDF products and summary CSV files (created if missing).",
)
@config_option()
@click.option("-q", "--quiet", is_flag=True, help="Print only failures.")
def sf_type(inputs: tuple[str, ...], outdir: str, config: str | None, quiet: bool) -> None:
    """Structure-function types of sonic FILES (TOA5, TOB1, GHG, Gill, Meteo-2).

    \b
    Gladkikh et al. (2014): per 10-min window and wind component (longitudinal,
    transverse, vertical) the normalised structure function is typed 1 (line),
    2 (parabola) or 3 (parabola then line) in lg-lg axes. Writes one product per
    file format and UTC day, <format>_<YYYYMMDD>_sf.nc, plus
    sf_type_occurrence.csv (Table 2) and sf_parameters.csv (Tables 3-5), and prints
    both tables. Exit status 0 when every input was processed, 1 otherwise, with one
    line per failed input naming the file, the line and the problem.
    """
    cfg = load_config_or_fail(config)
    files = expand_sonic_inputs(inputs)
    if not files:
        raise click.UsageError("no input files found")
    written, failures, products = run_sf_type(files, outdir, cfg)
    for line in failures:
        report_failure(line)
    if products:
        occurrence, stats = summary_tables(products)
        out = Path(outdir)
        occurrence.to_csv(out / "sf_type_occurrence.csv", float_format="%.2f")
        stats.to_csv(out / "sf_parameters.csv", index=False, float_format="%.4f")
        if not quiet:
            with pd.option_context("display.width", 120, "display.max_rows", 200):
                click.echo(
                    "Type occurrence (% of observed windows), Gladkikh et al. (2014) Table 2"
                )
                click.echo(occurrence.round(2).to_string())
                click.echo("\nParameter means and medians, Tables 3-5")
                click.echo(stats[stats["count"] > 0].round(4).to_string(index=False))
    if not quiet:
        for path in written:
            click.echo(f"wrote {path}")
        click.echo(
            f"{len(files)} input(s), {len(written)} product(s) written, {len(failures)} failure(s)"
        )
    sys.exit(0 if not failures else 1)
