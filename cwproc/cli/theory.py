"""``cwproc theory``: the physics of the papers as tables (and optional PNGs)."""

from __future__ import annotations

import click

from cwproc.cli.theory_eps import eps_ratio
from cwproc.cli.theory_vad import vad_errors
from cwproc.cli.theory_zephir import zephir_ratio


@click.group()
def theory() -> None:
    """Theory tables for planning and checking: epsilon bias, VAD errors, cw averaging."""


theory.add_command(eps_ratio)
theory.add_command(vad_errors)
theory.add_command(zephir_ratio)
