"""``cwproc eps-ratio`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("eps-ratio")
def eps_ratio() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'eps-ratio' is not available in this build yet")
