"""The ``cwproc`` command line: one module per command, thin (parse, call, report)."""

from __future__ import annotations

import click

from cwproc import __version__
from cwproc.cli.batch import batch
from cwproc.cli.info import info
from cwproc.cli.plot import plot
from cwproc.cli.retrieve import retrieve
from cwproc.cli.sf_type import sf_type
from cwproc.cli.simulate import simulate
from cwproc.cli.theory import theory


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, "-V", "--version", prog_name="cwproc")
def main() -> None:
    """cwproc: wind and turbulence products from Doppler lidars and sonic anemometers.

    \b
    Typical use:
      cwproc info FILE                       what a file is
      cwproc retrieve *.hpl -o out/          wind profile + dissipation rate (NetCDF)
      cwproc sf-type sonic/*.dat -o out/     structure-function types of sonic data
      cwproc theory eps-ratio --phi 60       method-1 / method-2 bias of epsilon
      cwproc simulate lidar -o sim/          a virtual Stream Line
      cwproc batch archive/ products/        incremental, locked runs (cron)
      cwproc plot out/x_wind.nc -o wind.png  quicklooks
    """


main.add_command(retrieve)
main.add_command(info)
main.add_command(sf_type)
main.add_command(theory)
main.add_command(simulate)
main.add_command(batch)
main.add_command(plot)
