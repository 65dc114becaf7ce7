"""``cwproc theory vad-errors``: predicted errors of the VAD wind fit (VAD accuracy paper).

Prints tables of the maximum errors (radial error bound Delta) and RMS errors (radial
error standard deviation sigma) of the three wind components for N uniformly spaced
azimuths at elevation phi, optionally with a missing azimuth sector, a linear
horizontal gradient and a tilted cone axis. x is the bisector of the missing sector
(and the direction of the gradient and of the tilt), y across it, z vertical.
"""

from __future__ import annotations

import click
import numpy as np

from cwproc.physics import vad_errors as ve
from cwproc.physics.geometry import scan_circle_radius

COMPONENTS = ("Vx", "Vy", "Vz")


def _table(title: str, columns: list[str], rows: dict[str, np.ndarray]) -> str:
    """A plain-text table: one row per wind component, one column per estimate."""
    width = max(12, *(len(c) + 2 for c in columns))
    lines = [title, "component".ljust(11) + "".join(c.rjust(width) for c in columns)]
    for i, name in enumerate(COMPONENTS):
        cells = "".join(f"{float(rows[c][i]):{width}.5f}" for c in columns)
        lines.append(name.ljust(11) + cells)
    return "\n".join(lines)


def _error_tables(phi: float, n: int, sector: float, bound: float | None, sigma: float | None):
    az = ve.uniform_azimuths_deg(n, sector)
    decoupled = ve.decoupled_weights(az, phi)
    ls = ve.least_squares_weights(az, phi)
    out = []
    if bound is not None:
        rows = {
            "decoupled": ve.max_errors(decoupled, bound),
            "least sq.": ve.max_errors(ls, bound),
        }
        if sector > 0:
            rows["N->inf eq.15"] = ve.max_error_sector_asymptotic(phi, sector, bound)
            rows["linear eq.16"] = ve.max_error_sector_linearised(phi, sector, bound)
        else:
            rows["N->inf eq.12"] = ve.max_error_full_circle_limit(phi, bound)
        out.append(
            _table(
                f"maximum errors (m s-1) for |radial error| <= {bound:g} m s-1 "
                "(VAD accuracy paper, eqs. 6, 12, 13, 15, 16)",
                list(rows),
                rows,
            )
        )
    if sigma is not None:
        rows = {
            "decoupled": ve.rms_errors(decoupled, sigma),
            "least sq.": ve.rms_errors(ls, sigma),
        }
        out.append(
            _table(
                f"RMS errors (m s-1) for radial error std {sigma:g} m s-1 "
                "(VAD accuracy paper, section 4)",
                list(rows),
                rows,
            )
        )
    return out


@click.command("vad-errors")
@click.option("--phi", type=float, default=35.3, show_default=True, help="Elevation (deg).")
@click.option(
    "--n-azimuths",
    "n_azimuths",
    type=int,
    default=24,
    show_default=True,
    help="Azimuths per full circle, uniformly spaced.",
)
@click.option(
    "--sector",
    type=float,
    default=0.0,
    show_default=True,
    help="Full width of a missing azimuth sector centred on x (deg).",
)
@click.option("--sigma", type=float, default=None, help="Radial error std (m s-1): RMS errors.")
@click.option(
    "--bound", type=float, default=None, help="Radial error bound (m s-1): maximum errors."
)
@click.option(
    "--range",
    "range_m",
    type=float,
    default=1000.0,
    show_default=True,
    help="Range along the beam (m) for the gradient and tilt terms.",
)
@click.option("--du-dx", "dvx_dx", type=float, default=0.0, help="Gradient dVx/dx (s-1).")
@click.option("--dv-dx", "dvy_dx", type=float, default=0.0, help="Gradient dVy/dx (s-1).")
@click.option("--tilt", type=float, default=0.0, help="Cone-axis tilt towards x (deg).")
@click.option(
    "--wind-x",
    "wind_x",
    type=float,
    default=10.0,
    show_default=True,
    help="Tilt term: wind along x (m s-1).",
)
@click.option(
    "--wind-z",
    "wind_z",
    type=float,
    default=0.0,
    show_default=True,
    help="Tilt term: vertical wind (m s-1).",
)
@click.option(
    "--shear-dz",
    "dvx_dz",
    type=float,
    default=0.0,
    show_default=True,
    help="Tilt term: vertical shear dVx/dz (s-1).",
)
def vad_errors_command(
    phi: float,
    n_azimuths: int,
    sector: float,
    sigma: float | None,
    bound: float | None,
    range_m: float,
    dvx_dx: float,
    dvy_dx: float,
    tilt: float,
    wind_x: float,
    wind_z: float,
    dvx_dz: float,
) -> None:
    """Predicted errors of the least-squares VAD wind fit (VAD accuracy paper).

    Without --sigma and --bound, both tables are printed per 1 m s-1 of radial error.
    x is the bisector of the missing sector and the direction of the gradient and tilt.
    """
    if sigma is not None and bound is not None:
        raise click.UsageError("give either --sigma or --bound, not both")
    if not 0.0 < phi < 90.0:
        raise click.UsageError("--phi must be between 0 and 90 degrees")
    if n_azimuths < 3:
        raise click.UsageError("--n-azimuths must be at least 3 (three unknowns)")
    if not 0.0 <= sector <= 180.0:
        raise click.UsageError("--sector must be between 0 and 180 degrees")
    for name, value in (("--sigma", sigma), ("--bound", bound), ("--range", range_m)):
        if value is not None and not value > 0:
            raise click.UsageError(f"{name} must be > 0")
    az = ve.uniform_azimuths_deg(n_azimuths, sector)
    if az.size < 3 or np.linalg.matrix_rank(ve.design_matrix(az, phi)) < 3:
        raise click.UsageError(
            f"the sector of {sector:g} deg leaves {az.size} azimuths: too few to fit a wind"
        )
    if sigma is None and bound is None:
        sigma, bound = 1.0, 1.0
    radius = float(scan_circle_radius(range_m * np.sin(np.deg2rad(phi)), phi))
    click.echo(
        f"VAD error theory (VAD accuracy paper): phi = {phi:g} deg, N = {n_azimuths} azimuths, "
        f"missing sector {sector:g} deg ({az.size} azimuths kept)"
    )
    click.echo("x = bisector of the missing sector / gradient / tilt direction; z = vertical")
    for table in _error_tables(phi, n_azimuths, sector, bound, sigma):
        click.echo("")
        click.echo(table)
    if dvx_dx or dvy_dx:
        rows = {
            "LS bias": ve.shear_bias(az, phi, radius, dvx_dx, dvy_dx),
            "bound eq.20": ve.shear_error_bound(az, phi, radius, dvx_dx, dvy_dx),
        }
        if sector == 0:
            rows["N->inf eq.23"] = ve.shear_error_bound_limit(phi, radius, dvx_dx, dvy_dx)
        click.echo("")
        click.echo(
            _table(
                f"linear horizontal gradient dVx/dx = {dvx_dx:g}, dVy/dx = {dvy_dx:g} s-1, "
                f"R' = {radius:.1f} m (m s-1; VAD accuracy paper, eqs. 19-23)",
                list(rows),
                rows,
            )
        )
    if tilt:
        rows = {
            "1st order": ve.tilt_bias_first_order(phi, tilt, wind_x, wind_z, dvx_dz, radius),
            "exact": ve.tilt_bias_exact(
                phi, tilt, [wind_x, 0.0, wind_z], dvx_dz, range_m, n_azimuths
            ),
        }
        click.echo("")
        click.echo(
            _table(
                f"cone axis tilted {tilt:g} deg towards x, V = ({wind_x:g}, 0, {wind_z:g}) "
                f"m s-1, dVx/dz = {dvx_dz:g} s-1 (m s-1; VAD accuracy paper, eq. 24; full circle)",
                list(rows),
                rows,
            )
        )
