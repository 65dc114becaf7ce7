"""Command groups that import a command's module only when that command runs.

``cwproc --version`` and ``cwproc --help`` then start without numpy, xarray or the
readers (a few tenths of a second instead of seconds), and every command pays only
for the modules it uses. The one-line help of each command in the group's listing is
kept here, next to the module name; ``tests/cli/test_startup.py`` checks it against
the command's own docstring.
"""

from __future__ import annotations

import atexit
import importlib
import os
import sys
from typing import Any, NoReturn

import click

from cwproc.memory import keep_freed_arrays


class LazyGroup(click.Group):
    """A click group whose sub-commands are ``name -> (module:attribute, one-line help)``."""

    def __init__(self, *args: Any, lazy: dict[str, tuple[str, str]], **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.lazy = lazy

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*self.commands, *self.lazy})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in self.lazy:
            module_name, attr = self.lazy[cmd_name][0].split(":")
            command = getattr(importlib.import_module(module_name), attr)
            self.add_command(command, cmd_name)
        return self.commands.get(cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command listing from the stored one-line helps (no module is imported)."""
        names = self.list_commands(ctx)
        if not names:
            return
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = []
        for name in names:
            if name in self.lazy:
                text = _shorten(self.lazy[name][1], limit)
            else:
                text = self.commands[name].get_short_help_str(limit)
            rows.append((name, text))
        with formatter.section("Commands"):
            formatter.write_dl(rows)


def _shorten(text: str, limit: int) -> str:
    """Cut ``text`` at a word boundary to ``limit`` characters, as click's short help does."""
    if len(text) <= limit:
        return text
    cut = text[: limit - 3].rsplit(" ", 1)[0]
    return cut + "..."


def keep_dask_out() -> bool:
    """Make ``import dask`` fail in this process, if neither dask nor xarray is imported yet.

    When dask is installed, xarray imports ``dask.array`` the first time it builds a
    variable (to test whether the data are a dask array) and ``dask.distributed`` on
    every ``to_netcdf`` (to ask which scheduler runs), about 0.5 s of imports for a
    command that never makes a dask array. With ``sys.modules["dask"] = None`` the
    import system raises ``ModuleNotFoundError`` and ``importlib.util.find_spec``
    returns None: xarray then runs as in an install without dask (the same products).
    xarray records whether dask is available when it is imported (and caches its
    answer), so the sentinel is set only before xarray's import, else never.

    Returns
    -------
    bool
        True when the sentinel was set, False when dask or xarray was already imported.
    """
    if "dask" in sys.modules or "xarray" in sys.modules:
        return False
    sys.modules["dask"] = None  # type: ignore[assignment]
    return True


def one_blas_thread() -> bool:
    """Have OpenBLAS start with one thread, unless numpy is imported or a count is set.

    numpy's wheels bring OpenBLAS, which starts a thread per core when numpy is
    imported; the threads spin while they wait for work before they sleep. A command
    without linear algebra (``sf-type``: transforms and element-wise work, no matrix
    product) pays that spin, about 0.1 s of CPU time on two cores, and gains nothing.
    ``OPENBLAS_NUM_THREADS=1`` is set in the environment, read by OpenBLAS when numpy
    loads it; a value the user set is kept.

    Returns
    -------
    bool
        True when the variable was set, False when numpy was already imported or the
        variable already set.
    """
    if "numpy" in sys.modules or "OPENBLAS_NUM_THREADS" in os.environ:
        return False
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    return True


def command_name(argv: list[str]) -> str | None:
    """The command of a ``cwproc`` command line (its first word that is not an option).

    The top-level options (``-h/--help``, ``-V/--version``) take no value, so the first
    word not starting with ``-`` names the command; None for ``cwproc --help``.
    """
    return next((word for word in argv if not word.startswith("-")), None)


class CwprocGroup(LazyGroup):
    """The top-level group: every usage error is one line on stderr with exit status 2.

    click prints a usage block, a hint and the error on four lines; cwproc prints
    ``error: cwproc plot: --time-index ... (see cwproc plot --help)``. Ctrl-C ends any
    command with one line and exit status 130 (:func:`interrupted`).

    When the group runs as the program (``args`` read from ``sys.argv``: the ``cwproc``
    script, ``python -m cwproc``), a command not in ``dask_commands`` runs with dask
    kept out of the process (:func:`keep_dask_out`) and the process ends without the
    interpreter's teardown (:func:`exit_now`); a command in ``array_commands`` also runs
    with freed arrays kept for reuse (:func:`keep_freed_arrays`), one in
    ``allocator_commands`` with the library's phases allowed to tune the allocator
    (:func:`cwproc.memory.tune_allocator`), and one in ``one_blas_thread_commands``
    with OpenBLAS on one thread (:func:`one_blas_thread`).
    Called with explicit arguments (a test, a notebook) the process is left as it is.
    """

    def __init__(
        self,
        *args: Any,
        dask_commands: frozenset[str],
        array_commands: frozenset[str] = frozenset(),
        allocator_commands: frozenset[str] = frozenset(),
        one_blas_thread_commands: frozenset[str] = frozenset(),
        **kwargs: Any,
    ) -> None:
        super().__init__(*args, **kwargs)
        self.dask_commands = dask_commands
        self.array_commands = array_commands
        self.allocator_commands = allocator_commands
        self.one_blas_thread_commands = one_blas_thread_commands

    def main(
        self, args: list[str] | None = None, *rest: Any, standalone_mode: bool = True, **kwargs: Any
    ) -> Any:
        name = command_name(sys.argv[1:])
        program = args is None and name not in self.dask_commands
        if program:
            keep_dask_out()
            if name in self.array_commands:
                keep_freed_arrays()
            if name in self.allocator_commands:
                from cwproc import memory

                memory.tune_allocator()
            if name in self.one_blas_thread_commands:
                one_blas_thread()
        if not standalone_mode:
            return super().main(args, *rest, standalone_mode=False, **kwargs)
        if not program:
            return self._run(args, *rest, **kwargs)
        try:
            self._run(args, *rest, **kwargs)
        except SystemExit as exc:
            exit_now(exc.code)

    def _run(self, *args: Any, **kwargs: Any) -> NoReturn:
        """Run the command; exit with its status (usage errors: one line, status 2)."""
        try:
            rv = super().main(*args, standalone_mode=False, **kwargs)
        except click.UsageError as exc:
            where = exc.ctx.command_path if exc.ctx is not None else "cwproc"
            message = " ".join(exc.format_message().split())
            click.echo(f"error: {where}: {message} (see {where} --help)", err=True)
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            click.echo(f"error: {' '.join(exc.format_message().split())}", err=True)
            sys.exit(exc.exit_code)
        except click.Abort as exc:
            if isinstance(exc.__cause__, KeyboardInterrupt):
                interrupted()
            click.echo("Aborted!", err=True)
            sys.exit(1)
        except KeyboardInterrupt:  # raised outside click's own handling (a callback)
            interrupted()
        sys.exit(rv if isinstance(rv, int) else 0)


#: exit status of a run stopped by Ctrl-C (SIGINT), the shells' 128 + 2
EXIT_INTERRUPTED = 130


def interrupted() -> NoReturn:
    """Ctrl-C: one line on stderr, no traceback, exit status :data:`EXIT_INTERRUPTED`.

    Products are published whole or not at all, so an interrupted run leaves the
    products it finished and no half-written file; ``cwproc batch`` redoes the unit in
    flight on its next run.
    """
    click.echo("interrupted (Ctrl-C): products finished so far are kept", err=True)
    sys.exit(EXIT_INTERRUPTED)


def exit_now(code: object) -> NoReturn:
    """End the process with the status ``sys.exit(code)`` gives, without its teardown.

    A command's work is done (products written and closed, its output printed) when it
    exits; tearing the interpreter down then (freeing every module of numpy, pandas,
    xarray, netCDF4 and the day's arrays) costs about 0.2 s of a 2.5-s ``sf-type``. The
    functions registered with :mod:`atexit` are run, the standard streams flushed, then
    :func:`os._exit` ends the process. Under a tracer or profiler (coverage,
    ``python -m cProfile``), which report at exit, the ordinary exit is kept.
    """
    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code
    else:  # sys.exit("message"): printed, status 1
        print(code, file=sys.stderr)
        status = 1
    if sys.gettrace() is not None or sys.getprofile() is not None:
        sys.exit(status)
    run_exit_functions = getattr(atexit, "_run_exitfuncs", None)  # CPython
    if run_exit_functions is None:
        sys.exit(status)
    run_exit_functions()  # what atexit promises (log handlers, a caller's own) still runs
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing more to say
            pass
    os._exit(status)
