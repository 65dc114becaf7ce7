"""``cwproc theory``: the physics of the papers as tables (and optional PNGs)."""

from __future__ import annotations

import click

from cwproc.cli._group import LazyGroup

COMMANDS = {
    "eps-ratio": (
        "cwproc.cli.theory_eps:eps_ratio_command",
        "Ratio eps1/eps2 of the dissipation rates of method 1 (no wind transport) and method 2.",
    ),
    "vad-errors": (
        "cwproc.cli.theory_vad:vad_errors_command",
        "Predicted errors of the least-squares VAD wind fit (VAD accuracy paper).",
    ),
    "zephir-ratio": (
        "cwproc.cli.theory_zephir:zephir_ratio_command",
        "Predicted lidar/cup standard-deviation ratio and TP variance share of a ZephIR.",
    ),
}


@click.group(cls=LazyGroup, lazy=COMMANDS)
def theory_command() -> None:
    """Theory tables for planning and checking: epsilon bias, VAD errors, cw averaging."""
