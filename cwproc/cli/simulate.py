"""``cwproc simulate``: the virtual instrument."""

from __future__ import annotations

import click

from cwproc.cli._group import LazyGroup

COMMANDS = {
    "lidar": (
        "cwproc.cli.simulate_lidar:simulate_lidar_command",
        "Files in the real formats from a virtual lidar, plus the truth that made them.",
    ),
    "mast": (
        "cwproc.cli.simulate_mast:simulate_mast_command",
        "Lidar .hpl files and a mast sonic's Meteo-2 file from one field, plus the truth.",
    ),
    "montecarlo": (
        "cwproc.cli.simulate_montecarlo:simulate_montecarlo_command",
        "Relative RMS errors of epsilon, sigma_V^2 and L_V versus the number of scans.",
    ),
    "sonic": (
        "cwproc.cli.simulate_sonic:simulate_sonic_command",
        "Synthetic Meteo-2 files (10.7 Hz, one per UTC day) with a prescribed SF type + truth.",
    ),
}


@click.group(cls=LazyGroup, lazy=COMMANDS)
def simulate_command() -> None:
    """Virtual lidars and sonics: files in the real formats plus the truth, and error studies."""
