"""``cwproc vad-errors`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("vad-errors")
def vad_errors() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'vad-errors' is not available in this build yet")
