"""``cwproc plot``: quicklook PNGs of products (and of one scan's VAD fit)."""

from __future__ import annotations

import sys
from typing import Any

import click

from cwproc.cli._common import (
    check_index,
    config_option,
    load_config_or_fail,
    report_failure,
    require_extra,
    usage_error,
)
from cwproc.errors import CwprocError

KIND_CHOICES = [
    "wind",
    "epsilon",
    "structure",
    "vad",
    "stare",
    "doppler-lidar",
    "sf-types",
    "sf-window",
    "montecarlo",
]


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
    default=None,
    help="structure: which block (time index) to draw [default: 0].",
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
@click.option(
    "--eps-range",
    type=(float, float),
    default=None,
    metavar="LO HI",
    help="epsilon: colour range in m2 s-3 [default: 1e-5 1e-1, the same for every file].",
)
@config_option()
def plot_command(
    source, out, kind, time_index, height, scan, window, component, eps_range, config
) -> None:
    """Draw a quicklook of SOURCE into a PNG.

    \b
    SOURCE is a cwproc product (.nc) or, for --kind vad, a scan file (.hpl or scan
    NetCDF) whose VAD fit is drawn with its residuals.
    \b
    kinds:
      wind        time-height of wind speed with direction barbs, and of w
                  (profiles for a product of one time step)
      epsilon     time-height of epsilon (method 2) and of eps1/eps2
                  (profiles for a product of one block)
      structure   D_L against lag with the fitted model and the noise floor
      vad         one scan: radial velocity against azimuth, fit and residuals
      stare       vertical stares: time-height of w (every ray), sigma_w^2 and
                  eps_stare (log scales; profiles for a product of one window)
      doppler-lidar  the L1 product (retrieve --l1): beta (fixed log range
                  1e-7 .. 1e-4 m-1 sr-1), depolarisation (0 .. 0.5), velocity
      sf-types    sonic: occurrence of each structure-function type per component
      sf-window   sonic: one window's normalised structure function with fit and r_max
      montecarlo  simulate montecarlo: relative errors against N per height

    Time-height pictures of epsilon use one log colour range for every file
    (--eps-range, default 1e-5 .. 1e-1 m2 s-3) and span the whole UTC day of the data,
    so that two days can be compared side by side.
    Options are checked against SOURCE before drawing: an index out of range or an
    option the kind does not use stops with one line (exit 2); a product with nothing
    to draw (every value missing) is refused with the reason (exit 1).
    """
    cfg = load_config_or_fail(config) if config is not None else None
    require_extra("matplotlib", "plot", "cwproc plot")
    _check_applicable(
        kind, time_index=time_index, scan=scan, window=window, component=component, eps=eps_range
    )
    if eps_range is not None and not 0 < eps_range[0] < eps_range[1]:
        usage_error(f"--eps-range {eps_range[0]:g} {eps_range[1]:g}: needs 0 < LO < HI")
    from cwproc import progress

    given = {
        "time_index": time_index,
        "height": height,
        "scan": scan,
        "window": window,
        "component": component,
        "eps_range": eps_range,
    }
    try:
        with (
            progress.reporting(progress.shown_on(quiet=False)),
            progress.bar(desc=f"plot {kind or ''}".strip(), total=2, unit="step") as steps,
        ):
            path = _draw(source, out, kind, cfg, steps, given)
    except CwprocError as exc:
        report_failure(str(exc))
        sys.exit(1)
    click.echo(f"wrote {path}")


def _draw(source: str, out: str, kind: str | None, cfg, steps, given: dict[str, Any]):
    """Read SOURCE (one step of ``steps``), check the options ``given`` against it, draw
    the PNG ``out`` (the second step); returns its path."""
    from cwproc import plots

    time_index, height, scan = given["time_index"], given["height"], given["scan"]
    window, component, eps_range = given["window"], given["component"], given["eps_range"]

    if kind == "vad":
        fig = _vad_figure(source, cfg, scan, height)
        steps.update(1)
        path = plots.save_png(fig, out)
    else:
        from cwproc.io.netcdf import read_product

        try:
            ds = read_product(source)
        except (OSError, ValueError) as exc:
            raise CwprocError(f"{source}: not a readable NetCDF product ({exc})") from None
        if kind is None:
            kind = plots.default_kind(ds)
        _check_applicable(
            kind,
            time_index=time_index,
            scan=scan,
            window=window,
            component=component,
            eps=eps_range,
        )
        plots.check_variables(ds, kind, str(source))
        options: dict[str, object] = {}
        if kind == "structure":
            check_index(
                time_index, ds.sizes.get("time", 0), "--time-index", f"time indices of {source}"
            )
            _check_height(height, ds["height"].values)
            options = {"time_index": time_index or 0, "height": height}
        elif kind == "sf-window":
            check_index(window, ds.sizes.get("window", 0), "--window", f"windows of {source}")
            if component is not None:
                names = [str(c) for c in ds["component"].values]
                if component not in names:
                    usage_error(f"--component {component!r}: {source} has {', '.join(names)}")
            options = {"window": window, "component": component}
        elif height is not None:
            usage_error(f"--height is used by --kind structure and vad, not {kind}")
        if kind == "epsilon":
            options = {"eps_range": eps_range}
        steps.update(1)
        path = plots.render(ds, kind, out, source=str(source), **options)
    steps.update(1)
    return path


#: option -> kinds that use it
_OPTION_KINDS = {
    "--time-index": ("structure",),
    "--scan": ("vad",),
    "--window": ("sf-window",),
    "--component": ("sf-window",),
    "--eps-range": ("epsilon",),
}


def _check_applicable(kind: str | None, **values: object) -> None:
    """Exit 2 when an option is given that ``kind`` does not use (it would be ignored)."""
    if kind is None:
        return
    for name, value in values.items():
        option = "--eps-range" if name == "eps" else "--" + name.replace("_", "-")
        if value is not None and kind not in _OPTION_KINDS[option]:
            usage_error(
                f"{option} is used by --kind {' and '.join(_OPTION_KINDS[option])}, not {kind}"
            )


def _check_height(height: float | None, heights) -> None:
    """Exit 2 when ``height`` lies beyond ``heights`` (m) by more than one gate."""
    if height is None:
        return
    import numpy as np

    h = np.asarray(heights, dtype=float)
    step = float(np.median(np.diff(h))) if h.size > 1 else 0.0
    if not h.min() - step <= height <= h.max() + step:
        usage_error(
            f"--height {height:g} is out of range: heights are {h.min():.0f} .. {h.max():.0f} m"
        )


def _vad_figure(source: str, cfg, scan: int | None, height: float | None):
    """Read one scan file, check --scan/--height against it, run its chain and draw the VAD."""
    import numpy as np

    from cwproc import plots
    from cwproc.config import Config
    from cwproc.pipeline import group_units, read_input, run_unit

    cfg = cfg if cfg is not None else Config()
    item = read_input(source, cfg)
    scans = item.dataset
    if "scan" not in scans.coords and "scan" not in scans:
        raise CwprocError(f"{source}: --kind vad needs a file of conical scans (no scan index)")
    present = np.unique(scans["scan"].values)
    present = present[present >= 0]
    if scan is not None and scan not in present:
        if present.size:
            usage_error(
                f"--scan {scan} is out of range: {source} has scans "
                f"{int(present.min())} .. {int(present.max())}"
            )
        usage_error(f"--scan {scan}: {source} holds no complete scan")
    if height is not None:
        el = np.radians(float(np.nanmedian(scans["elevation"].values)))
        _check_height(height, scans["range"].values * np.sin(el))
    # the chain of cwproc retrieve (background correction, qc, vad), on this file alone
    result = run_unit(group_units([item])[0], cfg, keep_screened=True)
    if not result.ok:
        raise CwprocError("; ".join(result.failures))
    if result.screened is None or "wind" not in result.products:
        raise CwprocError(f"{source}: --kind vad needs conical scans; the file holds none")
    return plots.plot_vad_fit(result.screened, result.products["wind"], scan=scan, height=height)
