"""The command line starts fast: listing and version import no command module, and the
stored one-line helps are the commands' own."""

from __future__ import annotations

import platform
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from cwproc import __version__
from cwproc.cli import COMMANDS, main
from cwproc.cli import simulate as simulate_group
from cwproc.cli import theory as theory_group
from cwproc.cli._group import command_name

SAMPLES = Path(__file__).resolve().parents[2] / "sample_data"


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
        "             ['retrieve', '--help'], ['sf-type', '--help'],\n"
        "             ['batch', '--help'], ['info', '--help']):\n"
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
    res = CliRunner().invoke(main, ["retrieve", "--no-such-option"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: main retrieve: No such option")
    assert "--no-such-option" in lines[0] and lines[0].endswith("(see main retrieve --help)")


#: run the command line as the program does (``main()`` reads ``sys.argv``); at its exit
#: (``exit_now``, or ``sys.exit`` for batch) print the status and whether dask was kept
#: out (the ``None`` sentinel) or imported
_AS_PROGRAM = (
    "import sys\n"
    "import cwproc.cli._group as group\n"
    "def report(code):\n"
    "    kept_out = 'dask' in sys.modules and sys.modules['dask'] is None\n"
    "    imported = 'dask.array' in sys.modules, 'distributed' in sys.modules\n"
    "    print(code, kept_out, *imported)\n"
    "    sys.stdout.flush()\n"
    "    group.os._exit(0)\n"
    "group.exit_now = report\n"
    "from cwproc.cli import main\n"
    "try:\n"
    "    main()\n"
    "except SystemExit as exc:\n"
    "    report(exc.code)\n"
)


def _as_program(*argv: str) -> list[str]:
    out = subprocess.run(
        [sys.executable, "-c", _AS_PROGRAM, *argv], capture_output=True, text=True
    ).stdout
    return out.splitlines()[-1].split()


def test_sf_type_runs_without_importing_dask(tmp_path):
    """With dask installed, ``cwproc sf-type`` imports neither dask.array nor distributed
    (xarray would, about 0.5 s of a 3-s run) and writes its product."""
    pytest.importorskip("dask")
    toa5 = SAMPLES / "sonic" / "TOA5_999.ts_data_2024_06_01_1200.dat"
    out = tmp_path / "out"
    assert _as_program("sf-type", str(toa5), "-o", str(out), "-q") == [
        "0",
        "True",
        "False",
        "False",
    ]
    assert len(list(out.glob("*_sf.nc"))) == 1


def test_batch_keeps_dask_importable():
    """``cwproc batch`` (``--scheduler`` runs on a Dask cluster) leaves dask importable."""
    pytest.importorskip("dask")
    assert _as_program("batch", "--help") == ["0", "False", "False", "False"]


def test_explicit_arguments_leave_the_process_alone():
    """A test or a notebook calling ``main([...])`` keeps its own import state."""
    res = CliRunner().invoke(main, ["sf-type", "--help"])
    assert res.exit_code == 0
    assert sys.modules.get("dask", "absent") is not None


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["sf-type", "a.dat", "-o", "out"], "sf-type"),
        (["-V"], None),
        (["--help", "batch"], "batch"),
    ],
)
def test_command_name_is_the_first_word_not_an_option(argv, name):
    assert command_name(argv) == name


def test_program_exit_keeps_output_and_status(tmp_path):
    """``cwproc`` ends without the interpreter's teardown: both streams are complete and
    the status is the command's (1: one of two inputs failed)."""
    toa5 = SAMPLES / "sonic" / "TOA5_999.ts_data_2024_06_01_1200.dat"
    missing = tmp_path / "missing.dat"
    res = subprocess.run(
        [sys.executable, "-m", "cwproc", "sf-type", str(toa5), str(missing), "-o", str(tmp_path)],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 1
    assert res.stdout.splitlines()[-1] == "2 input(s), 1 product(s) written, 1 failure(s)"
    assert res.stderr.splitlines() == [f"error: {missing}: cannot read: No such file or directory"]


def test_program_exit_runs_the_atexit_functions():
    """Ending without the teardown still runs what ``atexit`` promises (after the output)."""
    code = (
        "import atexit, sys\n"
        "atexit.register(lambda: print('exit function ran'))\n"
        "sys.argv = ['cwproc', '--version']\n"
        "from cwproc.cli import main\n"
        "main()\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0
    assert res.stdout.splitlines() == [
        f"cwproc, version {__version__}",
        "exit function ran",
    ]


#: page faults of allocating and freeing six 8-MB arrays ten times, in turn in a new
#: thread (as the reading threads) and in the main thread, with the allocator as it is
#: (argument 0) or after ``keep_freed_arrays`` (argument 1)
_FAULTS = (
    "import resource, sys, threading\n"
    "import numpy as np\n"
    "from cwproc.memory import keep_freed_arrays\n"
    "if sys.argv[1] == '1':\n"
    "    assert keep_freed_arrays()\n"
    "def arrays():\n"
    "    held = [np.ones(1 << 20) for _ in range(6)]\n"
    "    del held\n"
    "before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
    "for _ in range(5):\n"
    "    thread = threading.Thread(target=arrays)\n"
    "    thread.start()\n"
    "    thread.join()\n"
    "    arrays()\n"
    "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)\n"
)


def _huge_pages_always() -> bool:
    """Transparent huge pages on every mapping (faults then count 2-MiB pages)."""
    path = Path("/sys/kernel/mm/transparent_hugepage/enabled")
    return path.exists() and "[always]" in path.read_text()


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's mallopt")
@pytest.mark.skipif(_huge_pages_always(), reason="page faults counted in huge pages")
def test_freed_arrays_are_reused_without_new_pages():
    """After ``keep_freed_arrays`` the memory of freed arrays serves the next ones, in
    any thread: ten rounds of six 8-MB arrays, in turn in a new thread and in the main
    thread, touch fresh pages about once (12,300 pages of 4 KiB), against every round
    (about 117,000) with glibc's default, which unmaps them (and about twice with a
    heap per thread)."""
    import os

    env = {**os.environ, "NUMPY_MADVISE_HUGEPAGE": "0"}  # count 4-KiB pages, not 2-MiB
    runs = [
        subprocess.run(
            [sys.executable, "-c", _FAULTS, arg], capture_output=True, text=True, env=env
        )
        for arg in ("0", "1")
    ]
    assert [run.returncode for run in runs] == [0, 0], runs[1].stderr
    faults = [int(run.stdout) for run in runs]
    pages_per_round = 6 * (8 << 20) // 4096
    assert faults[0] > 5 * pages_per_round
    assert faults[1] < 1.5 * pages_per_round


def test_sf_type_program_keeps_freed_arrays_and_one_blas_thread_only_there():
    """The program runs ``sf-type`` with freed arrays kept for reuse and OpenBLAS on one
    thread (a count the user set is kept), ``simulate`` with one BLAS thread only; other
    commands and explicit calls leave the allocator and the environment alone."""
    import os

    from cwproc.cli import ARRAY_COMMANDS, ONE_BLAS_THREAD_COMMANDS

    assert ARRAY_COMMANDS == frozenset({"sf-type"})
    assert ONE_BLAS_THREAD_COMMANDS == frozenset({"sf-type", "simulate"})
    code = (
        "import os, sys\n"
        "import cwproc.cli._group as group\n"
        "calls = []\n"
        "group.keep_freed_arrays = lambda: calls.append(1) or True\n"
        "group.exit_now = lambda code: print(len(calls), os.environ.get('OPENBLAS_NUM_THREADS'))\n"
        "from cwproc.cli import main\n"
        "main()\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    cases = [
        (["sf-type", "--help"], env, "1 1"),
        (["info", "--help"], env, "0 None"),
        (["simulate", "--help"], env, "0 1"),  # one BLAS thread, the allocator as it is
        (["sf-type", "--help"], {**env, "OPENBLAS_NUM_THREADS": "2"}, "1 2"),
    ]
    for argv, environment, expected in cases:
        out = subprocess.run(
            [sys.executable, "-c", code, *argv],
            capture_output=True,
            text=True,
            check=True,
            env=environment,
        ).stdout
        assert out.splitlines()[-1] == expected, argv


@pytest.mark.parametrize(
    "table", [COMMANDS, simulate_group.COMMANDS, theory_group.COMMANDS], ids=["top", "sim", "th"]
)
def test_command_functions_say_they_are_commands(table):
    """A click command's function is ``<name>_command``: ``cwproc.retrieve`` (the API),
    ``stages.sonic_turbulence`` and ``physics``' ε-bias ratio keep their names alone."""
    import importlib

    for name, (target, _) in table.items():
        module, attr = target.split(":")
        assert attr.endswith("_command"), target
        assert getattr(importlib.import_module(module), attr).name == name
