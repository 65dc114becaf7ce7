"""``cwproc theory eps-ratio``: bias of the method-1 dissipation rate, Smalikho (2020), eq. 21."""

from __future__ import annotations

import math

import click
import numpy as np

from cwproc.cli._common import require_extra
from cwproc.physics.epsilon_bias import epsilon_bias_ratio as eps_ratio_values
from cwproc.physics.epsilon_bias import q1, q2
from cwproc.physics.transfer import PulsedProbe

#: default lag number l of Smalikho (2020), eq. 5 (see the command help)
DEFAULT_LAG = 3


def first_exceedance(mu: np.ndarray, ratio: np.ndarray, level: float = 1.1) -> float:
    """Smallest ``mu`` where ``ratio`` first rises above ``level`` (linear interpolation).

    Returns NaN when the ratio never exceeds ``level`` on the grid.
    """
    above = np.flatnonzero(ratio > level)
    if above.size == 0:
        return math.nan
    i = int(above[0])
    if i == 0:
        return float(mu[0])
    m0, m1, r0, r1 = mu[i - 1], mu[i], ratio[i - 1], ratio[i]
    return float(m0 + (level - r0) * (m1 - m0) / (r1 - r0))


def _write_png(path: str, mu: np.ndarray, ratio: np.ndarray, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    ax.plot(mu, ratio, color="k")
    ax.axhline(1.1, color="0.6", linestyle="--", linewidth=0.8)
    ax.set_xlabel(r"$\mu = U / V_s$")
    ax.set_ylabel(r"$\varepsilon_1 / \varepsilon_2$")
    ax.set_title(title, fontsize=9)
    ax.grid(True, linewidth=0.3)
    fig.tight_layout()
    try:
        fig.savefig(path)
    finally:
        plt.close(fig)


@click.command("eps-ratio")
@click.option(
    "--phi",
    "phi_deg",
    type=click.FloatRange(0, 90, min_open=True, max_open=True),
    required=True,
    help="Elevation angle of the scan cone (degrees).",
)
@click.option(
    "--dy",
    "dy",
    type=click.FloatRange(0, min_open=True),
    default=3.0,
    show_default=True,
    help="Transverse sampling dy = dtheta h / tan(phi) (m).",
)
@click.option(
    "--lag",
    "lag",
    type=click.IntRange(min=2),
    default=DEFAULT_LAG,
    show_default=True,
    help="Lag number l of the two-lag estimate (Smalikho (2020), eq. 5).",
)
@click.option(
    "--mu-max",
    type=click.FloatRange(0, 50, min_open=True),
    default=5.0,
    show_default=True,
    help="Largest mu = U / V_s of the table.",
)
@click.option(
    "--mu-step",
    type=click.FloatRange(0, min_open=True),
    default=0.25,
    show_default=True,
    help="Step of mu in the printed table.",
)
@click.option(
    "--transfer",
    type=click.Choice(["physical", "printed"]),
    default="physical",
    show_default=True,
    help="Gaussian term of the pulsed transfer function: with pi (physical) or as printed in "
    "eq. 19.",
)
@click.option(
    "--delta-p",
    type=click.FloatRange(0),
    default=15.3,
    show_default=True,
    help="Pulse half width dp = c sigma_p / 2 (m).",
)
@click.option(
    "--delta-r",
    type=click.FloatRange(0),
    default=18.0,
    show_default=True,
    help="Range-gate length dR = c T_w / 2 (m).",
)
@click.option("--png", "png", type=click.Path(dir_okay=False), help="Also plot to this PNG file.")
def eps_ratio_command(
    phi_deg: float,
    dy: float,
    lag: int,
    mu_max: float,
    mu_step: float,
    transfer: str,
    delta_p: float,
    delta_r: float,
    png: str | None,
) -> None:
    """Ratio eps1/eps2 of the dissipation rates of method 1 (no wind transport) and method 2.

    Smalikho (2020), eq. 21, for a pulsed lidar (Stream Line by default), against
    mu = U / V_s. The asymptotes q1(phi) mu (eq. 22, l dy >> probe length) and
    q2(phi) mu^2.5 (eq. 23, l dy mu << probe length) are printed alongside.

    \b
    Default lag number l = 3: the paper does not state it. With the physical
    transfer function l = 3 reproduces its three figure claims (ratio > 1.1 from
    mu = 0.53 at phi = 60, dy = 3 m [paper 0.55] and from mu = 1.10 at phi = 16,
    dy = 12 m [1.1]; ratio 4.17 at phi = 60, dy = 3 m, mu = 2.4 [~4]), it is the
    default lag of the retrieval ([turbulence] lag_number), and l dtheta stays within
    9 deg for dtheta <= 3 deg. l = 4 fits about as well (0.56, 1.10, 3.89).
    """
    if png:
        require_extra("matplotlib", "plot", "--png")
    probe = PulsedProbe(delta_p, delta_r, transfer)  # type: ignore[arg-type]
    n = round(mu_max / mu_step)
    mu = np.round(np.arange(n + 1) * mu_step, 10)
    mu = mu[mu <= mu_max + 1e-9]
    fine = np.linspace(0.0, mu_max, max(201, int(mu_max * 200) + 1))
    ratio_fine = eps_ratio_values(fine, phi_deg, dy, lag, probe=probe)
    ratio = eps_ratio_values(mu, phi_deg, dy, lag, probe=probe)
    a1 = float(q1(phi_deg))
    a2 = float(q2(phi_deg))
    click.echo(
        f"# eps1/eps2, Smalikho (2020) eq. 21: phi = {phi_deg:g} deg, dy = {dy:g} m, l = {lag}, "
        f"dp = {delta_p:g} m, dR = {delta_r:g} m, transfer = {transfer}"
    )
    mu_11 = first_exceedance(fine, ratio_fine)
    text = f"{mu_11:.3f}" if math.isfinite(mu_11) else f"not reached up to mu = {mu_max:g}"
    click.echo(f"# ratio first exceeds 1.1 at mu = {text}")
    click.echo(f"# q1(phi) = {a1:.4f} (eq. 22), q2(phi) = {a2:.4f} (eq. 23)")
    click.echo(f"{'mu':>8} {'eps1/eps2':>10} {'q1*mu':>10} {'q2*mu^2.5':>10}")
    for m, r in zip(mu, ratio, strict=True):
        click.echo(f"{m:8.3f} {r:10.4f} {a1 * m:10.4f} {a2 * m**2.5:10.4f}")
    if png:
        title = f"Smalikho (2020) eq. 21: phi={phi_deg:g} deg, dy={dy:g} m, l={lag}, {transfer}"
        try:
            _write_png(png, fine, ratio_fine, title)
        except OSError as exc:
            raise click.ClickException(f"{png}: cannot write: {exc.strerror or exc}") from None
        click.echo(f"# plot written to {png}")
