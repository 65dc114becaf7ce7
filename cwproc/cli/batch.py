"""``cwproc batch`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("batch")
def batch() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'batch' is not available in this build yet")
