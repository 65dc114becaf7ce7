"""``cwproc simulate sonic``: a virtual 10.7 Hz sonic with prescribed structure functions."""

from __future__ import annotations

import click

from cwproc.sim.sonic import write_simulation


@click.command("sonic")
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(file_okay=False),
    help="Directory for the Meteo-2 files and the truth JSON (created if missing).",
)
@click.option(
    "--type",
    "sf_type",
    type=click.IntRange(1, 3),
    default=2,
    show_default=True,
    help="Structure-function type (Gladkikh et al. (2014), eqs. 4-6).",
)
@click.option(
    "--hours",
    type=click.FloatRange(min=0.1, max=24 * 62),
    default=1.0,
    show_default=True,
    help="Record length (h).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option(
    "--speed",
    type=click.FloatRange(min=0.0, min_open=True),
    default=6.0,
    show_default=True,
    help="Mean horizontal wind (m/s).",
)
@click.option(
    "--start", default="2014-06-01T00:00:00", show_default=True, help="Start time (ISO, UTC)."
)
def simulate_sonic_command(
    outdir: str, sf_type: int, hours: float, seed: int, speed: float, start: str
) -> None:
    """Synthetic Meteo-2 files (10.7 Hz, one per UTC day) with a prescribed SF type + truth.

    \b
    Each wind component is a Gaussian process whose structure function is the chosen
    type of Gladkikh et al. (2014), eq. 7 (type 1: Kolmogorov slope 2/3; types 2 and 3:
    the all-site means of Tables 4-5). `cwproc sf-type` on the output recovers the
    type and parameters listed in the truth file.
    """
    try:
        files, truth = write_simulation(
            outdir, hours=hours, sf_type=sf_type, seed=seed, speed=speed, start=start
        )
    except (OSError, ValueError) as exc:
        raise click.ClickException(f"cannot simulate: {exc}") from None
    for path in files:
        click.echo(f"wrote {path}")
    click.echo(f"wrote {truth}")
