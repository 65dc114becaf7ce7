"""``cwproc compare``: lidar eps against sonic eps at the sonic's height."""

from __future__ import annotations

import click


@click.command("compare")
@click.argument("lidar_product", type=click.Path(dir_okay=False))
@click.argument("sonic_product", type=click.Path(dir_okay=False))
@click.option(
    "--height",
    "height_m",
    type=float,
    required=True,
    help="Height of the sonic on the lidar product's height axis (m).",
)
@click.option(
    "-o",
    "--output",
    "outdir",
    default=".",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Directory for the comparison product and its PNG (created if missing).",
)
@click.option(
    "--max-height-offset",
    type=click.FloatRange(min=0.0),
    default=25.0,
    show_default=True,
    help="Largest distance of the nearest lidar height from --height (m).",
)
@click.option(
    "--exclude-flags",
    type=click.IntRange(0, 255),
    default=None,
    help="turbulence_flag bits of the lidar product that leave a block out "
    "[default: 91 = 1+2+8+16+64; 4 and 32 leave epsilon usable].",
)
def compare_command(
    lidar_product: str,
    sonic_product: str,
    height_m: float,
    outdir: str,
    max_height_offset: float,
    exclude_flags: int | None,
) -> None:
    """Lidar eps against sonic eps: comparison product (NetCDF) and plot (PNG).

    \b
    Matches the lidar turbulence product's blocks (without the --exclude-flags bits) at the height
    nearest --height to the windows of a sonic turbulence product (cwproc
    sonic-turbulence), averages the blocks of each window, and writes
    lidar-sonic_<YYYYMMDD>_<H>m.nc (both dissipation rates with errors, their ratio,
    the sonic's stability and wind) and a PNG: log-log scatter with error bars, ratio
    against z/L and against wind speed. Prints the geometric-mean ratio and its spread.
    """
    from cwproc.cli._common import output_dir_or_exit
    from cwproc.errors import CwprocError, ProductError
    from cwproc.pipeline.compare import compare_files
    from cwproc.plots import write_comparison_png

    output_dir_or_exit(outdir)
    try:
        ds, path = compare_files(
            lidar_product,
            sonic_product,
            outdir,
            height_m=height_m,
            max_height_offset_m=max_height_offset,
            exclude_flag_mask=exclude_flags,
        )
    except CwprocError as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(f"wrote {path}")
    try:
        png = write_comparison_png(ds, path.with_suffix(".png"))
        click.echo(f"wrote {png}")
    except ProductError as exc:
        click.echo(f"note: no plot: {exc}", err=True)
    a = ds.attrs
    if a.get("summary_n_pairs", 0):
        click.echo(
            f"{a['summary_n_pairs']} windows at {float(ds['lidar_height']):.1f} m: lidar/sonic "
            f"geometric mean {a['summary_ratio_geometric_mean']:.3f} "
            f"(s.e. of mean ln ratio {a['summary_ratio_geometric_mean_relative_error']:.3f}), "
            "median "
            f"{a['summary_ratio_median']:.3f}, s.d. of lg ratio {a['summary_log10_ratio_std']:.3f}"
        )
    else:
        click.echo("no window has both a lidar and a sonic dissipation rate")
