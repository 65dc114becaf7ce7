"""``cwproc simulate montecarlo``: the error study of Banakh et al. (1999), Figs. 5-7."""

from __future__ import annotations

import math
from pathlib import Path

import click

from cwproc.cli._common import config_option, fail, load_config_or_fail, require_extra

#: stem of the files written (the study's paper)
STEM = "montecarlo_banakh1999"


@click.command("montecarlo")
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(file_okay=False),
    help=f"Directory for {STEM}.nc and .png (created if missing).",
)
@click.option(
    "--realisations",
    type=click.IntRange(min=2),
    default=None,
    help="Independent realisations (default: the config's, 1000 as in the paper).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option(
    "--png/--no-png",
    default=True,
    show_default=True,
    help="Also draw the errors (matplotlib, checked before the study runs).",
)
@config_option("banakh1999")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def simulate_montecarlo_command(
    outdir: str, realisations: int | None, seed: int, png: bool, config: str | None, quiet: bool
) -> None:
    """Relative RMS errors of epsilon, sigma_V^2 and L_V versus the number of scans.

    \b
    The virtual cw lidar of Banakh et al. (1999) (10.6 um, a0 = 7.5 cm, 30 deg, 7 s
    per scan, 140 spectra) at the six heights of the paper's table; N = 1..10 scans,
    1000 realisations. Prints the table and writes montecarlo_banakh1999.nc
    (epsilon_rel_error, variance_rel_error, integral_scale_rel_error,
    epsilon_mean_ratio over (n_scans, height)) and montecarlo_banakh1999.png.
    """
    if png:
        require_extra("matplotlib", "plot", f"the picture {STEM}.png (or pass --no-png)")
    from cwproc import progress
    from cwproc.errors import CwprocError
    from cwproc.products.writer import write_product
    from cwproc.references import BANAKH_1999
    from cwproc.sim.montecarlo import format_table, run_study

    cfg = load_config_or_fail(config)
    beam_radius = cfg.instrument.beam_radius_m
    if beam_radius is None:
        # z_R = c R^2 = lambda R^2 / (2 pi a0^2)
        beam_radius = math.sqrt(
            cfg.instrument.wavelength_m / (2.0 * math.pi * cfg.instrument.z_r_coefficient)
        )
    written: list[Path] = []
    try:
        with progress.reporting(progress.shown_on(quiet=quiet)):
            study = run_study(
                cfg.simulation,
                wavelength_m=cfg.instrument.wavelength_m,
                beam_radius_m=beam_radius,
                realisations=realisations,
                seed=seed,
            )
        out = Path(outdir)
        nc = write_product(
            study,
            out / f"{STEM}.nc",
            product="montecarlo",
            title="cwproc Monte-Carlo error study of Banakh et al. (1999)",
            summary=(
                "Relative RMS errors of the dissipation rate, velocity variance and integral "
                "scale estimated from N = 1..10 scans of a simulated cw Doppler lidar"
            ),
            config_toml=cfg.to_toml(),
            references=BANAKH_1999,
            keywords="Doppler lidar, Monte Carlo, dissipation rate, error",
            compression_level=cfg.output.compression_level,
        )
        written.append(nc)
        if png:
            from cwproc import plots

            written.append(plots.save_png(plots.plot_montecarlo(study), out / f"{STEM}.png"))
    except (CwprocError, OSError) as exc:
        fail(str(exc))
        return
    click.echo(format_table(study))
    for path in written:
        click.echo(f"wrote {path}")
