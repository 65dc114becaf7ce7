"""Helpers shared by the click commands: config loading and one-line error reports."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import click

from cwproc.config import Config, load_config, preset_names
from cwproc.errors import CwprocError


def config_option(default: str | None = None) -> Callable[[Any], Any]:
    """The ``-c/--config`` option: a TOML file or the name of a preset."""
    return click.option(
        "-c",
        "--config",
        "config",
        default=default,
        show_default=default is not None,
        metavar="FILE|PRESET",
        help=(
            "Configuration: a TOML file or a preset name "
            f"({', '.join(preset_names())})."
        ),
    )


def load_config_or_fail(value: str | None) -> Config:
    """Load the configuration; a bad one is a usage error (exit 2) with one clear line."""
    try:
        return load_config(value)
    except CwprocError as exc:
        raise click.UsageError(str(exc)) from None


def report_failure(message: str) -> None:
    """Print one failure line on stderr (``error: <file>:<line>: <problem>``)."""
    click.echo(f"error: {message}", err=True)


def fail(message: str, code: int = 1) -> None:
    """Print one failure line and exit with ``code``."""
    report_failure(message)
    sys.exit(code)
