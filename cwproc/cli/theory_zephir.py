"""``cwproc zephir-ratio`` (being built; see docs/DEVELOPING.md for the owner)."""

from __future__ import annotations

import click


@click.command("zephir-ratio")
def zephir_ratio() -> None:
    """Not available in this build yet."""
    raise click.ClickException("'zephir-ratio' is not available in this build yet")
