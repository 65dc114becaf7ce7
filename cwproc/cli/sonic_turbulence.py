"""``cwproc sonic-turbulence``: eps, variances, TKE, u_* and EC flags of sonic FILES.

Thin: parses the options and runs
:func:`cwproc.pipeline.sonic_turbulence.sonic_turbulence_files` (see docs/sonic.md).
"""

from __future__ import annotations

import sys

import click

from cwproc.cli._common import (
    inputs_or_exit,
    load_config_or_fail,
    output_dir_or_exit,
    product_command,
    report_failure,
)


@product_command("sonic-turbulence", "Directory for the NetCDF products (created if missing).")
@click.option(
    "--window",
    "window_s",
    type=click.FloatRange(min=60.0),
    default=1800.0,
    show_default=True,
    help="Averaging window (s).",
)
@click.option(
    "--despike",
    type=click.Choice(["vickers_mahrt", "mauder", "none"]),
    default="vickers_mahrt",
    show_default=True,
    help="Despiking: Vickers & Mahrt (1997) or Mauder et al. (2013), eq. 1.",
)
@click.option(
    "--rotation",
    type=click.Choice(["double", "planar_fit", "none"]),
    default="double",
    show_default=True,
    help="Coordinate rotation (Wilczak et al. (2001)).",
)
@click.option(
    "--detrend",
    type=click.Choice(["linear", "mean"]),
    default="linear",
    show_default=True,
    help="Detrending of the fluctuations.",
)
@click.option(
    "--height",
    "height_m",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    help="Measurement height (m) for the ITC test (untested without).",
)
@click.option(
    "--latitude",
    "latitude_deg",
    type=click.FloatRange(-90.0, 90.0),
    default=52.0,
    show_default=True,
    help="Latitude (degree) of the ITC model's Coriolis parameter.",
)
def sonic_turbulence_command(
    inputs: tuple[str, ...],
    outdir: str,
    config: str | None,
    quiet: bool,
    window_s: float,
    despike: str,
    rotation: str,
    detrend: str,
    height_m: float | None,
    latitude_deg: float,
) -> None:
    """Dissipation rate, variances, TKE, u_* and EC quality flags of sonic FILES.

    \b
    Per window (30 min by default): despiking, double rotation, detrending; eps from
    the inertial range of the structure functions, chosen from their Gladkikh et al.
    (2014) type (no inertial range: no eps, epsilon_flag says so), checked against the
    spectrum; sigma^2, TKE, u_*, integral scales with random errors; the steady-state
    and ITC tests of Foken & Wichura (1996) and the 0-1-2 flag. Writes
    <format>_<YYYYMMDD>_sonic-turbulence.nc per input format and UTC day. Exit
    status 0 when every input was processed, 1 otherwise.
    """
    cfg = load_config_or_fail(config)
    output_dir_or_exit(outdir)
    from cwproc.pipeline.sonic_turbulence import sonic_turbulence_files

    found = inputs_or_exit(inputs, cfg, quiet)
    report = sonic_turbulence_files(
        found.files,
        outdir,
        cfg,
        window_s=window_s,
        despike=despike,
        rotation=rotation,
        detrend=detrend,
        height_m=height_m,
        latitude_deg=latitude_deg,
    )
    for line in report.failures:
        report_failure(line)
    for line in report.notes:
        click.echo(f"note: {line}", err=True)
    if not quiet:
        for path in report.written:
            click.echo(f"wrote {path}")
    sys.exit(1 if report.failures or not (report.written or report.notes) else 0)
