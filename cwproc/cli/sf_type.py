"""``cwproc sf-type`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("sf-type")
def sf_type() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'sf-type' is not available in this build yet")
