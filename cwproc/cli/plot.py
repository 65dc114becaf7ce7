"""``cwproc plot``: quicklook PNGs of products (and of one scan's VAD fit)."""

from __future__ import annotations

import sys

import click

from cwproc.cli._common import config_option, load_config_or_fail, report_failure
from cwproc.errors import CwprocError

KIND_CHOICES = ["wind", "epsilon", "structure", "vad", "sf-types", "sf-window", "montecarlo"]


@click.command("plot")
@click.argument("source", type=click.Path(exists=True, dir_okay=False))
@click.option(
    "-o",
    "--output",
    "out",
    required=True,
    type=click.Path(dir_okay=False),
    help="PNG file to write.",
)
@click.option(
    "-k",
    "--kind",
    type=click.Choice(KIND_CHOICES),
    default=None,
    help="What to draw (default: chosen from the product's variables).",
)
@click.option(
    "--time-index",
    type=int,
    default=0,
    show_default=True,
    help="structure: which block (time index) to draw.",
)
@click.option(
    "--height",
    type=float,
    default=None,
    help="structure/vad: height (m) to draw (default: one with data).",
)
@click.option("--scan", type=int, default=None, help="vad: scan index (default: middle scan).")
@click.option("--window", type=int, default=None, help="sf-window: window index.")
@click.option("--component", default=None, help="sf-window: one component only.")
@config_option()
def plot(source, out, kind, time_index, height, scan, window, component, config) -> None:
    """Draw a quicklook of SOURCE into a PNG.

    \b
    SOURCE is a cwproc product (.nc) or, for --kind vad, a scan file (.hpl or scan
    NetCDF) whose VAD fit is drawn with its residuals.
    \b
    kinds:
      wind        time-height of wind speed with direction barbs, and of w
      epsilon     time-height of epsilon (method 2) and of eps1/eps2
      structure   D_L against lag with the fitted model and the noise floor
      vad         one scan: radial velocity against azimuth, fit and residuals
      sf-types    sonic: occurrence of each structure-function type per component
      sf-window   sonic: one window's normalised structure function with fit and r_max
      montecarlo  simulate montecarlo: relative errors against N per height
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        report_failure(
            'cwproc plot needs matplotlib: install the plot extra, pip install "cwproc[plot]"'
        )
        sys.exit(2)
    from cwproc import plots

    try:
        if kind == "vad":
            from cwproc.pipeline import read_input
            from cwproc.stages import qc, vad

            cfg = load_config_or_fail(config)
            scans = read_input(source, cfg).dataset
            screened = qc.screen_radial_velocity(
                scans, snr_min=cfg.qc.snr_min, outlier_threshold=cfg.qc.outlier_threshold
            )
            wind = vad.fit_vad(
                screened,
                min_rays=cfg.vad.min_rays,
                max_gap_deg=cfg.vad.max_gap_deg,
                reference_direction_deg=cfg.vad.reference_direction_deg,
                max_residual_std=cfg.vad.max_residual_std,
            )
            fig = plots.plot_vad_fit(screened, wind, scan=scan, height=height)
            path = plots.save_png(fig, out)
        else:
            from cwproc.io.netcdf import read_product

            try:
                ds = read_product(source)
            except (OSError, ValueError) as exc:
                raise CwprocError(f"{source}: not a readable NetCDF product ({exc})") from None
            kind = kind or plots.default_kind(ds)
            options = {}
            if kind == "structure":
                options = {"time_index": time_index, "height": height}
            elif kind == "sf-window":
                options = {"window": window, "component": component}
            path = plots.render(ds, kind, out, source=str(source), **options)
    except CwprocError as exc:
        report_failure(str(exc))
        sys.exit(1)
    click.echo(f"wrote {path}")
