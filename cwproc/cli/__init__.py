"""The ``cwproc`` command line: one module per command, thin (parse, call, report).

Commands are imported when they run (:mod:`cwproc.cli._group`), so that ``--version``
and ``--help`` start fast.
"""

from __future__ import annotations

import click

from cwproc._version import __version__
from cwproc.cli._group import CwprocGroup

#: command -> (module:attribute, one-line help = first line of its docstring)
COMMANDS = {
    "batch": (
        "cwproc.cli.batch:batch_command",
        "Process every new or changed input under INPUT_DIR into OUTPUT_DIR.",
    ),
    "compare": (
        "cwproc.cli.compare:compare_command",
        "Lidar eps against sonic eps: comparison product (NetCDF) and plot (PNG).",
    ),
    "info": (
        "cwproc.cli.info:info_command",
        "What each of FILES is: format, instrument, rays, gates, time span, scans.",
    ),
    "plot": ("cwproc.cli.plot:plot_command", "Draw a quicklook of SOURCE into a PNG."),
    "retrieve": (
        "cwproc.cli.retrieve:retrieve_command",
        "Wind profile and turbulence products from lidar or sonic FILES (or directories).",
    ),
    "sf-type": (
        "cwproc.cli.sf_type:sf_type_command",
        "Structure-function types of sonic FILES (TOA5, TOB1, GHG, Gill, Meteo-2).",
    ),
    "sonic-turbulence": (
        "cwproc.cli.sonic_turbulence:sonic_turbulence_command",
        "Dissipation rate, variances, TKE, u_* and EC quality flags of sonic FILES.",
    ),
    "simulate": (
        "cwproc.cli.simulate:simulate_command",
        "Virtual lidars and sonics: files in the real formats plus the truth, and error studies.",
    ),
    "theory": (
        "cwproc.cli.theory:theory_command",
        "Theory tables for planning and checking: epsilon bias, VAD errors, cw averaging.",
    ),
}

#: the commands that may use dask (``batch --scheduler``); the others run without it
DASK_COMMANDS = frozenset({"batch"})
#: the commands of array work without linear algebra, one day of one sonic at a time:
#: run with freed arrays kept for reuse (``keep_freed_arrays``: their temporaries are
#: allocated again and again) and OpenBLAS on one thread (``one_blas_thread``)
ARRAY_COMMANDS = frozenset({"sf-type"})
#: the commands whose process the library may tune for its phases of array work
#: (``cwproc.memory.tune_allocator``: a day's chunks, its dissipation-rate fit); a
#: notebook's or a test's process is left as it is
ALLOCATOR_COMMANDS = frozenset({"retrieve", "plot", "sf-type"})
#: the commands run with OpenBLAS on one thread (``one_blas_thread``): besides
#: ``sf-type``, ``simulate``, whose linear algebra is small (Cholesky factors of 140 x 140
#: B_D, matrix-vector products of quadrature weights): on two busy cores a second BLAS
#: thread made a 140 x 140 Cholesky 60 ms instead of 0.3 ms
ONE_BLAS_THREAD_COMMANDS = frozenset({"sf-type", "simulate"})


@click.group(
    cls=CwprocGroup,
    lazy=COMMANDS,
    dask_commands=DASK_COMMANDS,
    array_commands=ARRAY_COMMANDS,
    allocator_commands=ALLOCATOR_COMMANDS,
    one_blas_thread_commands=ONE_BLAS_THREAD_COMMANDS,
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)
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
