"""``cwproc simulate lidar``: instrument files made by the virtual lidar, plus the truth."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np

from cwproc import progress
from cwproc.cli._common import fail, usage_error
from cwproc.errors import CwprocError

if TYPE_CHECKING:
    from cwproc.sim.sample_data import StreamLineSpec

#: scans written when --hours is not given
_DEFAULT_HOURS = {"streamline": 0.2, "cw": 70.0 / 3600.0, "zephir": 60.0 / 3600.0}
#: ZephIR heights (m) of the simulated profile
_ZEPHIR_HEIGHTS = (40.0, 60.0, 80.0, 100.0, 150.0, 200.0)


@click.command("lidar")
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(file_okay=False),
    help="Directory: data files go to DIR/data/, the truth to DIR/truth/.",
)
@click.option(
    "--instrument",
    type=click.Choice(["streamline", "cw", "zephir"]),
    default="streamline",
    show_default=True,
    help="streamline: pulsed Stream Line VAD (.hpl); cw: the lidar of Banakh et al. "
    "(1999); zephir: ZephIR 300 (both cw: line-of-sight scan NetCDF, homodyne).",
)
@click.option(
    "--hours",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    help="Length of the series (h). Default: 0.2 (Stream Line), 10 scans (cw, ZephIR).",
)
@click.option("--wind", type=click.FloatRange(min=0.0), default=None, help="Wind speed (m/s).")
@click.option("--direction", type=float, default=240.0, show_default=True, help="Wind from (deg).")
@click.option(
    "--epsilon",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    help="Dissipation rate (m2/s3). Default 0.01 (Stream Line); cw: the paper's profile.",
)
@click.option(
    "--outer-scale",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    help="Integral scale L_V (m). Default 150 (Stream Line); cw: the paper's profile.",
)
@click.option(
    "--snr",
    type=click.FloatRange(min=0.0, min_open=True),
    default=0.05,
    show_default=True,
    help="Linear SNR of the Stream Line; sets the noise: 0.005/SNR m/s for the VADs, "
    "Pearson et al. (2009) for the stares.",
)
@click.option(
    "--scan",
    type=click.Choice(["vad", "stare", "mixed"]),
    default="vad",
    show_default=True,
    help="Stream Line only: VADs; vertical stares (one file per hour); or the daily cycle "
    "of the networks, a VAD every --vad-every minutes and stares in between, all from one "
    "turbulent field.",
)
@click.option(
    "--vad-every",
    type=click.FloatRange(min=1.0),
    default=15.0,
    show_default=True,
    help="Minutes between the VADs of --scan mixed.",
)
@click.option(
    "--gates",
    type=click.IntRange(min=1),
    default=24,
    show_default=True,
    help="Stream Line VADs: range gates per ray.",
)
@click.option(
    "--gate-length",
    type=click.FloatRange(min=1.0),
    default=30.0,
    show_default=True,
    help="Stream Line VADs: range gate length (m); gate centres (g + 0.5) x length.",
)
@click.option(
    "--scan-period",
    type=click.FloatRange(min=1.0),
    default=36.0,
    show_default=True,
    help="Stream Line VADs: seconds per 180-ray scan (a VAD every that many seconds).",
)
@click.option(
    "--scans-per-file",
    type=click.IntRange(min=1),
    default=10,
    show_default=True,
    help="Stream Line VADs: scans in each .hpl file (1: one file per VAD, as the Halo "
    "writes them).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def simulate_lidar_command(
    outdir: str,
    instrument: str,
    hours: float | None,
    wind: float | None,
    direction: float,
    epsilon: float | None,
    outer_scale: float | None,
    snr: float,
    scan: str,
    vad_every: float,
    gates: int,
    gate_length: float,
    scan_period: float,
    scans_per_file: int,
    seed: int,
    quiet: bool,
) -> None:
    """Files in the real formats from a virtual lidar, plus the truth that made them.

    \b
    Stream Line: a frozen von Karman field advected by the wind, scanned at 35.3 deg
    (180 rays per --scan-period s, --gates gates of --gate-length m; default 36 s, 24
    gates of 30 m), written as .hpl files in DIR/data/;
    --scan stare / mixed: vertical stares (20000 pulses, 1.33 s rays, noise of
    Pearson et al. (2009) at --snr) of the same field, alone or between the VADs.
    cw / zephir: Doppler spectra and centroid velocities of Banakh et al. (1999)
    (eq. 17 field, corrected Q_s, homodyne |V_r|), written as scan NetCDF.
    The truth (wind, epsilon, L_V, sigma_V^2) goes to DIR/truth/truth.json, outside
    the data folder, so that `cwproc retrieve DIR/data -o out/` reads only data.
    """
    _check_scan_options(instrument, scan)
    out = Path(outdir)
    data, truth = out / "data", out / "truth" / "truth.json"
    hours = _DEFAULT_HOURS[instrument] if hours is None else hours
    geometry = {
        "n_gates": gates,
        "gate_length_m": gate_length,
        "scan_period_s": scan_period,
        "scans_per_file": scans_per_file,
    }
    try:
        with progress.reporting(progress.shown_on(quiet=quiet)):
            written = _simulate(
                instrument, scan, data, truth, hours, vad_every, geometry,
                wind, direction, epsilon, outer_scale, snr, seed,
            )  # fmt: skip
    except (CwprocError, OSError, ValueError) as exc:
        fail(str(exc))
        return
    for line in written_lines(written):
        click.echo(line)


#: more data files than this are named by their first and last, in one line
_FILES_NAMED = 4


def written_lines(written: list[Path]) -> list[str]:
    """``wrote`` lines of a simulation: each data file, or one line for a long series
    (``wrote 1920 files DIR/FIRST .. LAST``; a day would print 1920 lines), then the truth.
    """
    *data, truth = written
    if len(data) <= _FILES_NAMED:
        return [f"wrote {path}" for path in written]
    return [f"wrote {len(data)} files {data[0]} .. {data[-1].name}", f"wrote {truth}"]


def _simulate(
    instrument: str,
    scan: str,
    data: Path,
    truth: Path,
    hours: float,
    vad_every: float,
    geometry: dict[str, float],
    wind: float | None,
    direction: float,
    epsilon: float | None,
    outer_scale: float | None,
    snr: float,
    seed: int,
) -> list[Path]:
    """Run the instrument's simulation; the files written, truth last."""
    if instrument == "streamline" and scan != "vad":
        return _streamline_stares(
            data, truth, scan, hours, vad_every, wind, direction, epsilon, outer_scale, snr, seed
        )
    if instrument == "streamline":
        return _streamline(
            data, truth, hours, geometry, wind, direction, epsilon, outer_scale, snr, seed
        )
    return _cw(data, truth, instrument, hours, wind, direction, epsilon, outer_scale, seed)


def _check_scan_options(instrument: str, scan: str) -> None:
    """Exit 2 when an option does not fit the instrument or scan (it would be ignored)."""
    ctx = click.get_current_context()
    if instrument != "streamline" and scan != "vad":
        usage_error(f"--scan {scan} needs --instrument streamline (got --instrument {instrument})")

    def given(name: str) -> bool:
        return ctx.get_parameter_source(name) is click.core.ParameterSource.COMMANDLINE

    if given("vad_every") and scan != "mixed":
        usage_error(f"--vad-every is used by --scan mixed only, not --scan {scan}")
    vads = instrument == "streamline" and scan == "vad"
    for name in ("gates", "gate_length", "scan_period", "scans_per_file"):
        if given(name) and not vads:
            option = "--" + name.replace("_", "-")
            usage_error(
                f"{option} is used by Stream Line VADs only (--instrument streamline --scan vad)"
            )


def _streamline(
    data: Path,
    truth: Path,
    hours: float,
    geometry: dict[str, float],
    wind: float | None,
    direction: float,
    epsilon: float | None,
    outer_scale: float | None,
    snr: float,
    seed: int,
) -> list[Path]:
    from cwproc.sim.sample_data import StreamLineSpec, noise_from_snr, write_streamline_series

    base = StreamLineSpec()
    gate = float(geometry["gate_length_m"])
    spec = _streamline_spec(
        wind,
        direction,
        epsilon,
        outer_scale,
        snr,
        seed,
        n_scans=max(1, round(hours * 3600.0 / geometry["scan_period_s"])),
        scans_per_file=int(geometry["scans_per_file"]),
        n_gates=int(geometry["n_gates"]),
        gate_length_m=gate,
        scan_period_s=float(geometry["scan_period_s"]),
        # nodes that divide the gate (7.5 m for 30 m gates): the gates share them
        range_step_m=gate / np.ceil(gate / base.field_spacing_m),
        noise_std=noise_from_snr(snr),
    )
    return write_streamline_series(data, truth, spec)


def _streamline_spec(
    wind: float | None,
    direction: float,
    epsilon: float | None,
    outer_scale: float | None,
    snr: float,
    seed: int,
    **more: object,
) -> StreamLineSpec:
    """The sample Stream Line spec with the command's wind, turbulence, SNR and seed."""
    from cwproc.sim.sample_data import StreamLineSpec

    base = StreamLineSpec()
    return dataclasses.replace(
        base,
        start="2024-01-01T00:00:00",
        wind_speed=base.wind_speed if wind is None else wind,
        wind_direction_deg=direction,
        epsilon=base.epsilon if epsilon is None else epsilon,
        integral_scale_m=base.integral_scale_m if outer_scale is None else outer_scale,
        snr=snr,
        seed=seed,
        **more,
    )


def _streamline_stares(
    data: Path,
    truth: Path,
    scan: str,
    hours: float,
    vad_every_min: float,
    wind: float | None,
    direction: float,
    epsilon: float | None,
    outer_scale: float | None,
    snr: float,
    seed: int,
) -> list[Path]:
    from cwproc.sim.stare import write_stare_series

    spec = _streamline_spec(wind, direction, epsilon, outer_scale, snr, seed)
    return write_stare_series(
        data, truth, spec, scan=scan, hours=hours, vad_every_s=60.0 * vad_every_min
    )


def _cw(
    data: Path,
    truth: Path,
    instrument: str,
    hours: float,
    wind: float | None,
    direction: float,
    epsilon: float | None,
    outer_scale: float | None,
    seed: int,
) -> list[Path]:
    from cwproc.config import load_config
    from cwproc.physics.dissipation import epsilon_from_integral_scale
    from cwproc.physics.spectra import variance_from
    from cwproc.sim.cw import ZEPHIR, write_cw_series
    from cwproc.sim.montecarlo import lidar_from_config

    sim = load_config("banakh1999").simulation
    if instrument == "cw":
        lidar = lidar_from_config(sim, 10.6e-6, 0.075)
        heights = np.asarray(sim.heights_m)
        speed = np.asarray(sim.wind_speed_m_s)
        sigma2 = np.asarray(sim.sigma_v_m_s) ** 2
        scale = np.asarray(sim.outer_scale_m)
    else:
        lidar = ZEPHIR
        heights = np.asarray(_ZEPHIR_HEIGHTS)
        speed = np.full(heights.size, 8.0)
        scale = np.full(heights.size, 150.0)
        sigma2 = variance_from(0.01, scale)
    if wind is not None:
        speed = np.full(heights.size, wind)
    if epsilon is not None or outer_scale is not None:
        eps = (
            epsilon_from_integral_scale(sigma2, scale)
            if epsilon is None
            else np.full(heights.size, epsilon)
        )
        scale = scale if outer_scale is None else np.full(heights.size, outer_scale)
        sigma2 = variance_from(eps, scale)
    n_scans = max(1, round(hours * 3600.0 / lidar.scan_period_s))
    return write_cw_series(
        data,
        truth,
        np.random.default_rng(seed),
        lidar,
        heights_m=heights,
        wind_speed=speed,
        wind_direction_deg=direction,
        sigma2=sigma2,
        outer_scale_m=scale,
        n_scans=n_scans,
        start=np.datetime64("2024-01-01T00:00:00"),
    )
