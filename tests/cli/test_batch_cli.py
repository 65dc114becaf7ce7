"""``cwproc batch`` on the command line: options, exit codes, messages, log lines."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from cwproc.batch import EXIT_LOCKED, STATE_DIR, dask_client, load_ledger, output_lock
from cwproc.cli import main
from cwproc.errors import CwprocError

HPL_READER_MISSING = importlib.util.find_spec("cwproc.io.halo") is None


def invoke(*args: str):
    return CliRunner().invoke(main, ["batch", *args], catch_exceptions=False)


def junk_archive(root: Path) -> Path:
    """Two files cwproc does not read (and a hidden one it never looks at)."""
    (root / "sub").mkdir(parents=True)
    (root / "notes.md").write_text("field notes\n")
    (root / "sub" / "empty.dat").write_bytes(b"")
    (root / ".hidden.hpl").write_text("Filename:\tx\n")
    return root


def test_help_names_every_option():
    result = invoke("--help")
    assert result.exit_code == 0
    options = ("--since", "--workers", "--scheduler", "--pattern", "--wait", "--min-age")
    for option in (*options, "--log-file", "--quiet", "--verbose", "--config"):
        assert option in result.output
    assert "75" in result.output  # the exit status of a locked output directory


def test_unrecognised_files_are_counted_and_listed_with_verbose(tmp_path):
    inputs = junk_archive(tmp_path / "in")
    result = invoke(str(inputs), str(tmp_path / "out"))
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines()[-1].startswith(
        "2 file(s): 2 unrecognised, 0 refused (unreadable or another instrument); 0 unit(s)"
    )
    verbose = invoke(str(inputs), str(tmp_path / "out"), "--verbose")
    assert verbose.exit_code == 0
    listed = [line for line in verbose.stdout.splitlines() if line.startswith("unrecognised:")]
    assert len(listed) == 2
    assert any("notes.md:1: not a format cwproc reads" in line for line in listed)
    assert any("empty.dat: file is empty" in line for line in listed)
    quiet = invoke(str(inputs), str(tmp_path / "out"), "--quiet")
    assert quiet.exit_code == 0 and quiet.output == ""


def test_log_file_gets_key_value_lines(tmp_path):
    inputs = junk_archive(tmp_path / "in")
    log = tmp_path / "batch.log"
    result = invoke(str(inputs), str(tmp_path / "out"), "--quiet", "--log-file", str(log))
    assert result.exit_code == 0
    (line,) = log.read_text().splitlines()
    assert re.fullmatch(
        r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ INFO event=plan files=2 classified=2 units=0 "
        r"todo=0 up_to_date=0",
        line,
    )


def test_second_run_on_a_locked_output_exits_75_naming_the_holder(tmp_path):
    inputs = junk_archive(tmp_path / "in")
    out = tmp_path / "out"
    with output_lock(out / STATE_DIR):
        result = invoke(str(inputs), str(out))
    assert result.exit_code == EXIT_LOCKED
    assert "another cwproc batch run (pid=" in result.stderr
    assert "Traceback" not in result.output


def test_stale_lock_of_a_dead_run_is_taken_over_and_reported(tmp_path):
    inputs = junk_archive(tmp_path / "in")
    state = tmp_path / "out" / STATE_DIR
    state.mkdir(parents=True)
    (state / "lock").write_text("pid=4242 host=elsewhere started=2026-01-01T00:00:00Z\n")
    result = invoke(str(inputs), str(tmp_path / "out"))
    assert result.exit_code == 0
    assert (
        "took over the lock of a run that ended abnormally "
        "(pid=4242 host=elsewhere started=2026-01-01T00:00:00Z)" in result.stdout
    )
    assert (state / "lock").read_text() == ""  # released cleanly at the end


def test_unwritable_state_folder_is_one_clear_line(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / STATE_DIR).write_text("a file where the state folder belongs\n")
    result = invoke(str(junk_archive(tmp_path / "in")), str(out))
    assert result.exit_code == 1
    assert result.stderr == (
        f"error: {out / STATE_DIR / 'lock'}: cannot create the lock: File exists\n"
    )


def test_scheduler_without_dask_explains_how_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    monkeypatch.setitem(sys.modules, "distributed", None)
    result = invoke(
        str(junk_archive(tmp_path / "in")), str(tmp_path / "out"), "--scheduler", "tcp://x:1"
    )
    assert result.exit_code == 2
    assert 'pip install "cwproc[dask]"' in result.stderr


def test_local_workers_need_no_dask(tmp_path, monkeypatch):
    """--workers N is a process pool of the standard library."""
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    monkeypatch.setitem(sys.modules, "distributed", None)
    result = invoke(str(junk_archive(tmp_path / "in")), str(tmp_path / "out"), "--workers", "2")
    assert result.exit_code == 0, result.stderr
    assert "pip install" not in result.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--workers", "2", "--scheduler", "tcp://x:1"], "not both"),
        (["--since", "2024-13-01"], "'2024-13-01' does not match"),
        (["--workers", "0"], "0"),
        (["-c", "no-such-preset"], "no such preset"),
        (["--quiet", "--verbose"], "not both"),
    ],
)
def test_usage_errors_exit_2(tmp_path, args, message):
    result = invoke(str(junk_archive(tmp_path / "in")), str(tmp_path / "out"), *args)
    assert result.exit_code == 2
    assert message in result.stderr


@pytest.mark.parametrize(
    "address", ["foo", "inproc://x", "http://host:8786", "", "tcp://host", "tcp://h:99999"]
)
def test_bad_scheduler_addresses_are_usage_errors(tmp_path, address):
    """One line, exit 2, no traceback and no silent serial run (issue 17.7)."""
    result = invoke(
        str(junk_archive(tmp_path / "in")), str(tmp_path / "out"), "--scheduler", address
    )
    assert result.exit_code == 2
    assert "not a Dask scheduler address" in result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    assert not (tmp_path / "out").exists()


def test_tls_scheduler_without_tls_settings_is_a_usage_error(tmp_path):
    pytest.importorskip("dask")
    result = invoke(
        str(junk_archive(tmp_path / "in")), str(tmp_path / "out"), "--scheduler", "tls://h:8786"
    )
    assert result.exit_code == 2
    assert "TLS settings" in result.stderr


def test_unreachable_scheduler_is_a_clear_error():
    pytest.importorskip("dask.distributed")
    with pytest.raises(CwprocError, match=r"cannot reach the Dask scheduler tcp://127\.0\.0\.1:9"):
        dask_client(scheduler="tcp://127.0.0.1:9", timeout_s=1.0)


@pytest.mark.skipif(HPL_READER_MISSING, reason="the Halo reader cwproc.io.halo is not built yet")
def test_real_corrupt_file_is_reported_with_its_line_and_retried(real_data, tmp_path):
    inputs = real_data / "hpl"  # read in place, never copied
    corrupt = inputs / "CORRUPT_warsaw-2021-10-01-Stare_213_20211001_18.hpl"
    good = inputs / "eriswil-2022-12-14-Stare_91_20221214_11.hpl"
    out, log = tmp_path / "out", tmp_path / "log"
    patterns = ("--pattern", corrupt.name, "--pattern", good.name)
    args = (str(inputs), str(out), *patterns, "--log-file", str(log))
    first = invoke(*args)
    assert first.exit_code == 1
    pattern = rf"error: {re.escape(str(inputs / corrupt.name))}:\d+: "
    assert len(re.findall(pattern, first.stderr)) == 1
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert ledger.failures[str(inputs / corrupt.name)]["attempts"] == 1
    assert str(inputs / good.name) in ledger.files
    second = invoke(*args)
    assert second.exit_code == 1
    assert len(re.findall(pattern, second.stderr)) == 1
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert ledger.failures[str(inputs / corrupt.name)]["attempts"] == 2
    file_lines = [line for line in log.read_text().splitlines() if "event=file " in line]
    assert len(file_lines) == 2 and all("status=failed" in line for line in file_lines)


@pytest.mark.skipif(HPL_READER_MISSING, reason="the .hpl reader is not installed")
def test_files_in_a_row_that_held_the_same_get_one_note(tmp_path):
    """Six one-scan files of a day: batch prints one note for them, as retrieve does."""
    from cwproc.sim.sample_data import StreamLineSpec, write_streamline_series

    spec = StreamLineSpec(n_scans=6, scans_per_file=1, n_gates=24, seed=5)
    write_streamline_series(tmp_path / "in", tmp_path / "truth.json", spec)
    files = sorted((tmp_path / "in").glob("*.hpl"))
    result = invoke(str(tmp_path / "in"), str(tmp_path / "out"), "--config", "streamline")
    assert result.exit_code == 0, result.output
    notes = [line for line in result.output.splitlines() if "conical scan(s)" in line]
    assert len(files) == 6 and len(notes) == 1, result.output
    assert notes[0].startswith(f"note: 6 files {files[0]} .. {files[-1]}: ")


def test_noted_files_are_the_existing_files_notes_begin_with(tmp_path):
    from cwproc.cli._common import noted_files

    (tmp_path / "a.hpl").write_text("x")
    notes = [f"{tmp_path / 'a.hpl'}: VAD: 1 conical scan(s)", "turbulence not computed: no block"]
    notes.append(f"{tmp_path / 'gone.hpl'}: VAD: 1 conical scan(s)")
    assert noted_files(notes) == [str(tmp_path / "a.hpl")]
