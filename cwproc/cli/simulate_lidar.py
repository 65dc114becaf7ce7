"""``cwproc lidar`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("lidar")
def simulate_lidar() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'lidar' is not available in this build yet")
