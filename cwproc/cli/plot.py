"""``cwproc plot`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("plot")
def plot() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'plot' is not available in this build yet")
