"""``cwproc simulate mast``: a virtual Stream Line and a mast sonic in one frozen field."""

from __future__ import annotations

import click


@click.command("mast")
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(file_okay=False),
    help="Directory for lidar/*.hpl, mast/*.txt and truth.json (created if missing).",
)
@click.option(
    "--hours",
    type=click.FloatRange(min=0.5, max=24.0),
    default=1.0,
    show_default=True,
    help="Record length (h).",
)
@click.option(
    "--epsilon",
    type=click.FloatRange(min=0.0, min_open=True),
    default=0.01,
    show_default=True,
    help="Dissipation rate of the field (m2 s-3).",
)
@click.option(
    "--mast-height",
    type=click.FloatRange(min=1.0, max=60.0),
    default=26.0,
    show_default=True,
    help="Height of the sonic above the lidar (m).",
)
@click.option("--seed", type=int, default=1, show_default=True, help="Seed of the field.")
def simulate_mast_command(
    outdir: str, hours: float, epsilon: float, mast_height: float, seed: int
) -> None:
    """Lidar .hpl files and a mast sonic's Meteo-2 file from one field, plus the truth.

    \b
    One frozen von Karman field (L_V 300 m, 1 m fine grid with a 16 m coarse level)
    carried by a 6 m/s wind is scanned by a virtual Stream Line (35.3 deg, 30 m gates)
    and sampled at 10 Hz by a sonic on a mast at the lidar, inside its cone. Run
    `cwproc retrieve OUT/lidar`, `cwproc sonic-turbulence OUT/mast --height H` and
    `cwproc compare ... --height H` for a comparison whose truth is known (the field's
    eps; for the sonic, the field's own structure function on its grid: docs/sonic.md).
    """
    from cwproc.sim.mast import MastCase, write_mast_case

    case = MastCase(
        hours=hours,
        epsilon=epsilon,
        integral_scale_m=300.0,
        mast_height_m=mast_height,
        seed=seed,
    )
    try:
        written = write_mast_case(outdir, case)
    except (OSError, ValueError) as exc:
        raise click.ClickException(f"cannot simulate: {exc}") from None
    for path in written["lidar"]:
        click.echo(f"wrote {path}")
    click.echo(f"wrote {written['mast']}")
    click.echo(f"wrote {written['truth']}")
