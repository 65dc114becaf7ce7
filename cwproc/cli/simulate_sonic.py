"""``cwproc sonic`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("sonic")
def simulate_sonic() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'sonic' is not available in this build yet")
