"""The command line starts fast: listing and version import no command module, and the
stored one-line helps are the commands' own."""

from __future__ import annotations

import subprocess
import sys

import pytest

from cwproc.cli import COMMANDS, main
from cwproc.cli import simulate as simulate_group
from cwproc.cli import theory as theory_group


@pytest.mark.parametrize(
    "table", [COMMANDS, simulate_group.COMMANDS, theory_group.COMMANDS], ids=["top", "sim", "th"]
)
def test_listing_help_is_the_commands_docstring(table):
    import importlib

    for name, (target, short) in table.items():
        module, attr = target.split(":")
        command = getattr(importlib.import_module(module), attr)
        assert command.help.split("\n")[0].strip() == short, name


def test_help_and_version_import_no_heavy_module():
    code = (
        "import sys\n"
        "from click.testing import CliRunner\n"
        "from cwproc.cli import main\n"
        "for args in (['--help'], ['--version'], ['theory', '--help'], ['plot', '--help'],\n"
        "             ['retrieve', '--help']):\n"
        "    assert CliRunner().invoke(main, args).exit_code == 0\n"
        "heavy = [m for m in ('numpy', 'xarray', 'pandas', 'scipy', 'netCDF4') "
        "if m in sys.modules]\n"
        "print(','.join(heavy))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == ""


def test_usage_errors_are_one_line_exit_2():
    from click.testing import CliRunner

    res = CliRunner().invoke(main, ["retrieve", "--no-such-option"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: main retrieve: No such option")
    assert "--no-such-option" in lines[0] and lines[0].endswith("(see main retrieve --help)")
