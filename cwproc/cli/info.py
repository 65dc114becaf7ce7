"""``cwproc info`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("info")
def info() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'info' is not available in this build yet")
