"""``cwproc montecarlo`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("montecarlo")
def simulate_montecarlo() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'montecarlo' is not available in this build yet")
