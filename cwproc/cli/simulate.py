"""``cwproc simulate``: the virtual instrument."""

from __future__ import annotations

import click

from cwproc.cli.simulate_lidar import simulate_lidar
from cwproc.cli.simulate_montecarlo import simulate_montecarlo
from cwproc.cli.simulate_sonic import simulate_sonic


@click.group()
def simulate() -> None:
    """Virtual lidars and sonics: files in the real formats plus the truth, and error studies."""


simulate.add_command(simulate_lidar, "lidar")
simulate.add_command(simulate_sonic, "sonic")
simulate.add_command(simulate_montecarlo, "montecarlo")
