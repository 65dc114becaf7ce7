"""``cwproc theory zephir-ratio``: volume averaging of a ZephIR (Wagner et al. (DTU)).

Prints, per height, the focus range R, the probe half width Z_R, the scan length
scale l_az, the predicted ratio sigma_lidar / sigma_cup of the 10-min standard
deviations of the wind speed and the share of the cup variance that the turbulence
parameter TP carries, ``(TP U)² / sigma_cup²`` (:mod:`cwproc.physics.volume_averaging`).
"""

from __future__ import annotations

import click

from cwproc.physics import volume_averaging as va
from cwproc.physics.constants import ZEPHIR_Z_R_COEFFICIENT


def parse_heights(text: str) -> list[float]:
    """Heights from ``"40,60 80"`` (commas and/or spaces), each > 0 (m)."""
    parts = [p for p in text.replace(",", " ").split() if p]
    try:
        heights = [float(p) for p in parts]
    except ValueError:
        raise click.BadParameter(
            f"{text!r} is not a list of numbers", param_hint="--heights"
        ) from None
    if not heights or any(not h > 0 for h in heights):
        raise click.BadParameter("give one or more heights > 0 (m)", param_hint="--heights")
    return heights


def ratio_table(
    heights: list[float],
    wind_speed: float,
    scan_times: list[float],
    z_r_coefficient: float,
    window_s: float,
) -> str:
    """The plain-text table of the command."""
    head = f"{'h (m)':>7}{'R (m)':>9}{'Z_R (m)':>9}"
    for t in scan_times:
        head += f"{f'l_az {t:g}s':>11}{f'ratio {t:g}s':>11}{f'TP var {t:g}s':>12}"
    lines = [head]
    for h in heights:
        row = f"{h:7.1f}{float(va.focus_range(h)):9.1f}"
        row += f"{float(va.zephir_rayleigh_range(h, z_r_coefficient)):9.2f}"
        for t in scan_times:
            ratio, share = va.std_ratio_and_tp_share(
                h, wind_speed, t, z_r_coefficient=z_r_coefficient, window_s=window_s
            )
            row += f"{float(va.azimuth_length_scale(h, wind_speed, t)):11.1f}"
            row += f"{ratio:11.3f}{share:12.3f}"
        lines.append(row)
    return "\n".join(lines)


@click.command("zephir-ratio")
@click.option(
    "--heights",
    default="40,60,80,100,150,200",
    show_default=True,
    help="Heights above the lidar (m), comma- or space-separated.",
)
@click.option(
    "--wind-speed",
    "wind_speed",
    type=float,
    default=8.0,
    show_default=True,
    help="Mean horizontal wind speed U (m s-1).",
)
@click.option(
    "--scan-time",
    "scan_time",
    type=click.Choice(["1", "3"]),
    default=None,
    help="Scan duration behind one wind value (s); both when omitted.",
)
@click.option(
    "--z-r-coefficient",
    "z_r_coefficient",
    type=float,
    default=ZEPHIR_Z_R_COEFFICIENT,
    show_default=True,
    help="c of Z_R = c R^2 (1/m).",
)
@click.option(
    "--window",
    "window_s",
    type=float,
    default=600.0,
    show_default=True,
    help="Averaging window of the standard deviations (s).",
)
def zephir_ratio_command(
    heights: str,
    wind_speed: float,
    scan_time: str | None,
    z_r_coefficient: float,
    window_s: float,
) -> None:
    """Predicted lidar/cup standard-deviation ratio and TP variance share of a ZephIR.

    Wagner et al. (DTU): Kaimal spectrum, Lorentzian probe Z_R = c R^2 at
    R = h / cos 30 deg, conical-scan filter over l_az = 2 h tan 30 deg + U T_scan.
    """
    hs = parse_heights(heights)
    for name, value in (
        ("--wind-speed", wind_speed),
        ("--z-r-coefficient", z_r_coefficient),
        ("--window", window_s),
    ):
        if not value > 0:
            raise click.BadParameter("must be > 0", param_hint=name)
    times = [float(scan_time)] if scan_time else [1.0, 3.0]
    click.echo(
        f"ZephIR volume averaging (Wagner et al. (DTU)): U = {wind_speed:g} m s-1, "
        f"Z_R = {z_r_coefficient:g} R^2, {window_s:g}-s statistics"
    )
    click.echo("ratio = sigma_lidar / sigma_cup;  TP var = (TP U)^2 / sigma_cup^2")
    click.echo(ratio_table(hs, wind_speed, times, z_r_coefficient, window_s))
