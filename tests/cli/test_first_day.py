"""A new user's first day (issue 30, item 5): what the first runs of each command do.

Ctrl-C, a wrong configuration, an unwritable or reused ``-o``, a product with nothing in
it, other instruments' files among the inputs, ``info -c`` and progress (item 4).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc import progress
from cwproc.cli import main

SAMPLES = Path(__file__).resolve().parents[2] / "sample_data"
HPL = SAMPLES / "streamline"


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture
def one_scan_file(tmp_path: Path) -> Path:
    folder = tmp_path / "in"
    folder.mkdir()
    shutil.copy(next(HPL.glob("*.hpl")), folder)
    return folder


# ---------------------------------------------------------------- Ctrl-C: exit 130


def _interrupt(*_args, **_kwargs):
    raise KeyboardInterrupt


@pytest.mark.parametrize(
    ("target", "args"),
    [
        ("cwproc.pipeline.retrieve_files", ["retrieve", HPL, "-o", "{out}"]),
        ("cwproc.pipeline.retrieve_files", ["sf-type", SAMPLES / "sonic", "-o", "{out}"]),
        ("cwproc.batch.run_batch", ["batch", HPL, "{out}"]),
        ("cwproc.cli.describe.describe_file", ["info", next(HPL.glob("*.hpl"))]),
        (
            "cwproc.plots.plot_vad_fit",
            ["plot", next(HPL.glob("*.hpl")), "--kind", "vad", "-o", "{out}/v.png"],
        ),
    ],
    ids=["retrieve", "sf-type", "batch", "info", "plot"],
)
def test_ctrl_c_exits_130_with_one_line(monkeypatch, tmp_path, target, args):
    module, name = target.rsplit(".", 1)
    monkeypatch.setattr(__import__(module, fromlist=[name]), name, _interrupt)
    res = run(*[str(a).format(out=tmp_path / "o") for a in args])
    assert res.exit_code == 130, res.output
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "interrupted" in lines[0], res.output
    assert "Traceback" not in res.output


# ------------------------------------------- a configuration of another instrument


def test_a_cw_preset_on_stream_line_files_is_an_error_naming_both(one_scan_file, tmp_path):
    out = tmp_path / "o"
    res = run("retrieve", "-c", "zephir300", one_scan_file, "-o", out)
    assert res.exit_code == 1, res.output
    (line,) = [x for x in res.output.splitlines() if x.startswith("error:")]
    name = next(one_scan_file.glob("*.hpl"))
    assert str(name) in line and "Stream Line" in line and "ZephIR 300" in line
    assert "-c streamline" in line
    assert list(out.glob("*.nc")) == []


def test_batch_refuses_the_same_files_with_the_same_line(one_scan_file, tmp_path):
    res = run("batch", "-c", "zephir300", one_scan_file, tmp_path / "b")
    assert res.exit_code == 1, res.output
    assert "ZephIR 300" in res.output and "Stream Line" in res.output
    assert list((tmp_path / "b").glob("*.nc")) == []


# ------------------------------------------------------------ -o checked first


def test_an_output_that_cannot_be_a_directory_stops_before_any_input_is_read(
    monkeypatch, one_scan_file, tmp_path
):
    import cwproc.pipeline

    def must_not_run(*_a, **_k):
        raise AssertionError("inputs read before -o was checked")

    monkeypatch.setattr(cwproc.pipeline, "retrieve_files", must_not_run)
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for command in (["retrieve", one_scan_file], ["sf-type", SAMPLES / "sonic"]):
        res = run(*command, "-o", blocker / "sub")
        assert res.exit_code == 2, res.output
        assert str(blocker / "sub") in res.output and "cannot write products" in res.output


def test_a_missing_output_is_created(one_scan_file, tmp_path):
    out = tmp_path / "new" / "deeper"
    assert run("retrieve", one_scan_file, "-o", out, "-q").exit_code == 0
    assert sorted(p.name.split("_")[-1] for p in out.glob("*.nc")) == [
        "turbulence.nc",
        "wind.nc",
    ]


# ------------------------------------------------------- a second run into one -o


def test_a_second_run_replaces_its_products_with_a_note(one_scan_file, tmp_path):
    out = tmp_path / "o"
    first = run("retrieve", one_scan_file, "-o", out)
    assert first.exit_code == 0 and "replaced" not in first.output
    second = run("retrieve", one_scan_file, "-o", out)
    assert second.exit_code == 0, second.output
    (note,) = [x for x in second.output.splitlines() if "of an earlier run replaced" in x]
    assert note.startswith("note: 2 product(s)")
    assert all(str(p) in note for p in out.glob("*.nc"))


# ---------------------------------------------------- no product of nothing at all


def test_a_product_whose_every_value_is_missing_is_not_written_and_the_note_says_why():
    from cwproc.config import Config
    from cwproc.pipeline.run import empty_reason

    eps = np.full((2, 3), np.nan)
    ds = xr.Dataset(
        {
            "epsilon": (("time", "height"), eps),
            "turbulence_flag": (("time", "height"), np.full((2, 3), 16, np.int16)),
        }
    )
    reason = empty_reason("turbulence", ds, Config())
    assert "no turbulence product written" in reason and "partial_block 6/6" in reason
    assert "n_scans = 10" in reason
    assert empty_reason("turbulence", ds.fillna(0.01), Config()) == ""


@pytest.mark.slow
def test_a_mixed_day_with_too_few_vads_gets_no_empty_turbulence_product(tmp_path):
    sim = tmp_path / "sim"
    made = run("simulate", "lidar", "-o", sim, "--scan", "mixed", "--hours", "0.5")
    assert made.exit_code == 0, made.output
    res = run("retrieve", sim / "data", "-o", tmp_path / "o")
    assert res.exit_code == 0, res.output
    assert not list((tmp_path / "o").glob("*_turbulence.nc"))
    assert "no turbulence product written: every epsilon is missing" in res.output


# ------------------------------------------------ other instruments: one note


def test_the_other_instruments_files_get_one_note(tmp_path):
    res = run("retrieve", SAMPLES, "-c", SAMPLES / "site.toml", "-o", tmp_path / "o")
    assert res.exit_code == 0, res.output
    skipped = [x for x in res.output.splitlines() if "other instruments" in x]
    assert len(skipped) == 1
    assert skipped[0].startswith("note: 15 files of other instruments skipped")
    for fmt in (
        "ghg",
        "gill",
        "meteo2",
        "toa5",
        "tob1",
        "windcube_rtd",
        "windcube_sta",
        "zephir_csv",
    ):
        assert fmt in skipped[0]


# -------------------------------------------------------------------- info -c


def test_info_reads_the_gill_sample_with_the_reader_settings_of_a_configuration():
    gill = next((SAMPLES / "sonic").glob("gill_*"))
    bare = run("info", gill)
    assert bare.exit_code == 1 and "[reader.gill]" in bare.output
    res = run("info", "-c", SAMPLES / "sonic.toml", gill)
    assert res.exit_code == 0, res.output
    assert "2024-06-01T12:00:00.000Z" in res.output and "time=6000" in res.output


# ------------------------------------------- configuration errors come first


@pytest.mark.parametrize("command", ["retrieve", "sf-type", "batch", "info", "plot"])
def test_a_configuration_typo_is_reported_before_the_pipeline_is_imported(tmp_path, command):
    bad = tmp_path / "typo.toml"
    bad.write_text('[instrument]\nknd = "pulsed"\n')
    args = {
        "retrieve": ["retrieve", str(HPL), "-o", str(tmp_path / "o")],
        "sf-type": ["sf-type", str(HPL), "-o", str(tmp_path / "o")],
        "batch": ["batch", str(HPL), str(tmp_path / "o")],
        "info": ["info", str(next(HPL.glob("*.hpl")))],
        "plot": ["plot", str(next(HPL.glob("*.hpl"))), "--kind", "vad", "-o", "x.png"],
    }[command] + ["-c", str(bad)]
    code = (
        "import sys\n"
        "from click.testing import CliRunner\n"
        "from cwproc.cli import main\n"
        f"res = CliRunner().invoke(main, {args!r})\n"
        "print(res.exit_code)\n"
        "print(res.output.strip())\n"
        "print(','.join(m for m in ('cwproc.pipeline', 'xarray', 'numpy') if m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    assert out[0] == "2"
    assert "instrument.knd: unknown key" in out[1] and str(bad) in out[1]
    assert out[-1] == ""  # nothing heavy imported, no input read: told at once
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------- progress


def test_no_bar_where_stderr_is_not_a_terminal(one_scan_file, tmp_path, monkeypatch):
    monkeypatch.setattr(progress, "DELAY_S", 0.0)
    res = run("retrieve", one_scan_file, "-o", tmp_path / "o")
    assert res.exit_code == 0
    assert "processing" not in res.output and "it/s" not in res.output


@pytest.mark.parametrize("command", ["retrieve", "batch", "sf-type", "plot"])
def test_a_bar_when_progress_is_on(one_scan_file, tmp_path, monkeypatch, command):
    monkeypatch.setattr(progress, "DELAY_S", 0.0)
    monkeypatch.setattr(progress, "shown_on", lambda *, quiet, stream=None: not quiet)
    args, bar = {
        "retrieve": (["retrieve", one_scan_file, "-o", tmp_path / "o"], "processing"),
        "batch": (["batch", one_scan_file, tmp_path / "o"], "units"),
        "sf-type": (
            ["sf-type", SAMPLES / "sonic", "-c", SAMPLES / "sonic.toml", "-o", tmp_path / "o"],
            "reading",
        ),
        "plot": (
            ["plot", next(one_scan_file.glob("*.hpl")), "--kind", "vad", "-o", tmp_path / "v.png"],
            "plot vad",
        ),
    }[command]
    res = run(*args)
    assert res.exit_code == 0, res.output
    assert bar in res.output
    quiet = run(*args, "-q") if command != "plot" else None
    if quiet is not None:
        assert quiet.exit_code == 0 and bar not in quiet.output
