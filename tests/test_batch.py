"""Machinery of ``cwproc batch``: discovery, ledger, fingerprints, --since, lock.

Most tests drive :func:`cwproc.batch.run_batch` with a *toy* backend defined here
(``toy_classify``/``toy_process``: a one-column text format whose product is the mean of
its values), so that the ledger and lock logic is exercised with inputs whose every
byte the test controls. The products are still written by the real
:func:`cwproc.pipeline.write_unit_products` (atomic, CF metadata). The last test runs
the real pipeline on synthetic Stream Line files with a known wind.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import errno
import importlib.util
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.batch import (
    STATE_DIR,
    FileInfo,
    LockBusyError,
    UnitOutcome,
    UnitTask,
    before_since,
    config_hash,
    discover_files,
    file_older_than,
    kv_line,
    load_ledger,
    output_lock,
    peak_rss_mib,
    run_batch,
    save_ledger,
    unit_fingerprint,
)
from cwproc.config import Config, QCConfig, config_from_toml
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import Format
from cwproc.io.netcdf import read_product, sha256_file

# --------------------------------------------------------------------------------------
# the toy backend (also used by test_batch_faults.py and by Dask workers)
# --------------------------------------------------------------------------------------

TOY_MAGIC = "# cwproc batch toy"


def write_toy(path: Path, system: str, day: str, values, hour: int = 0) -> Path:
    """A toy input: magic line, ``system=<id> time=<ISO>``, then one value per line."""
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [TOY_MAGIC, f"system={system} time={day}T{hour:02d}:00:00"]
    lines += [repr(float(v)) for v in values]
    path.write_text("\n".join(lines) + "\n")
    return path


def read_toy(path: str) -> xr.Dataset:
    """Read a toy file; bad lines raise InputFileError with the line number."""
    lines = Path(path).read_text().splitlines()
    if len(lines) < 3 or lines[0] != TOY_MAGIC:
        raise InputFileError(path, "not a toy file", 1)
    try:
        fields = dict(item.split("=", 1) for item in lines[1].split())
        system, start = fields["system"], np.datetime64(fields["time"], "ns")
    except (ValueError, KeyError):
        raise InputFileError(path, "bad header", 2) from None
    values = []
    for number, text in enumerate(lines[2:], start=3):
        try:
            values.append(float(text))
        except ValueError:
            raise InputFileError(path, f"not a number: {text!r}", number) from None
    return xr.Dataset(
        {"value": ("sample", np.array(values))},
        coords={"time": ("sample", np.full(len(values), start))},
        attrs={"system_id": system, "instrument": "toy"},
    )


def toy_classify(path: str, config_toml: str, config_source: str = "") -> FileInfo:
    """Classification of a toy file (the toy counterpart of ``classify_file``)."""
    st = os.stat(path)
    base = FileInfo(
        path,
        st.st_size,
        st.st_mtime_ns,
        "unrecognised",
        config_hash=config_hash(config_from_toml(config_toml, source=config_source)),
    )
    with open(path, "rb") as fh:
        head = fh.read(64)
    if not head.startswith(TOY_MAGIC.encode()):
        return dataclasses.replace(base, error=f"{path}:1: not a toy file")
    try:
        ds = read_toy(path)
    except InputFileError as exc:
        return FileInfo(path, st.st_size, st.st_mtime_ns, "error", error=str(exc))
    day = np.datetime_as_string(ds["time"].values[0], unit="D")
    return FileInfo(
        path,
        st.st_size,
        st.st_mtime_ns,
        "ok",
        sha256=sha256_file(path),
        format="toy",
        kind="scan",
        unit=f"toy_{ds.attrs['system_id']}_{day.replace('-', '')}",
        start=day + "T00:00:00Z",
        config_hash=base.config_hash,
    )


def toy_process(task: UnitTask) -> UnitOutcome:
    """Product of a toy unit: ``wind_speed(time, height)`` = mean of the inputs' values.

    ``CWPROC_TOY_SLEEP`` (s) slows it down and ``CWPROC_TOY_JOURNAL`` names a file to
    which the unit key is appended once its products are written (fault tests).
    """
    from cwproc.pipeline import InputFile, ProductUnit, write_unit_products

    t0 = time.perf_counter()
    config = config_from_toml(task.config_toml, source=task.config_source)
    try:
        datasets = [read_toy(p) for p in task.paths]
        values = np.concatenate([d["value"].values for d in datasets])
        product = xr.Dataset(
            {"wind_speed": (("time", "height"), np.full((1, 2), values.mean()))},
            coords={
                "time": ("time", [min(d["time"].values.min() for d in datasets)]),
                "height": ("height", [100.0, 200.0]),
            },
        )
        unit = ProductUnit(
            key=task.key,
            kind=task.kind,
            inputs=[
                InputFile(Path(p), Format.HPL, s, d)
                for p, s, d in zip(task.paths, task.sha256, datasets, strict=True)
            ],
        )
        time.sleep(float(os.environ.get("CWPROC_TOY_SLEEP", "0")))
        written = write_unit_products(unit, {"wind": product}, task.outdir, config)
    except CwprocError as exc:
        return UnitOutcome(task.key, task.fingerprint, error=str(exc))
    journal = os.environ.get("CWPROC_TOY_JOURNAL")
    if journal:
        with open(journal, "a") as fh:
            fh.write(task.key + "\n")
    return UnitOutcome(
        task.key,
        task.fingerprint,
        products=tuple(map(str, written)),
        seconds=time.perf_counter() - t0,
        peak_rss_mib=peak_rss_mib(),
        pid=os.getpid(),
    )


def toy_archive(root: Path, n_days: int = 3, files_per_day: int = 2, system: str = "A"):
    """``n_days`` toy units of ``files_per_day`` files each, in nested folders."""
    rng = np.random.default_rng(1234)
    paths = []
    for d in range(n_days):
        day = f"2024-01-{d + 1:02d}"
        for h in range(files_per_day):
            values = rng.normal(5.0 + d, 1.0, size=20)
            paths.append(write_toy(root / day / f"scan_{h:02d}.txt", system, day, values, h))
    return paths


def run_toy(inputs: Path, outdir: Path, config: Config | None = None, **kw):
    return run_batch(
        inputs,
        outdir,
        config or Config(),
        classify=toy_classify,
        process=toy_process,
        **kw,
    )


def mean_of(paths) -> float:
    return float(np.concatenate([read_toy(str(p))["value"].values for p in paths]).mean())


# --------------------------------------------------------------------------------------
# pure helpers
# --------------------------------------------------------------------------------------


def test_fingerprint_ignores_input_order_but_not_content_or_config():
    a, b = "a" * 64, "b" * 64
    h1, h2 = config_hash(Config()), config_hash(Config(qc=QCConfig(snr_min=0.02)))
    assert unit_fingerprint([a, b], h1) == unit_fingerprint([b, a], h1)
    assert unit_fingerprint([a, b], h1) != unit_fingerprint([a, a], h1)
    assert unit_fingerprint([a, b], h1) != unit_fingerprint([a, b], h2)


def test_config_hash_depends_on_content_not_on_where_it_came_from():
    text = Config().to_toml()
    assert config_hash(config_from_toml(text, source="/a/x.toml")) == config_hash(
        config_from_toml(text, source="<preset streamline>")
    )


def test_kv_line_quotes_values_with_blanks_and_round_trips():
    line = kv_line("unit", unit="toy_A_20240101", error="x.hpl:12: not a number", n=3)
    assert line.startswith("event=unit unit=toy_A_20240101 ")
    assert 'error="x.hpl:12: not a number"' in line
    assert line.endswith("n=3")


def test_since_helpers():
    since = dt.date(2024, 1, 2)
    assert before_since("2024-01-01T23:59:59Z", since)
    assert not before_since("2024-01-02T00:00:00Z", since)
    assert not before_since("", since)
    midnight_ns = int(dt.datetime(2024, 1, 2, tzinfo=dt.UTC).timestamp()) * 10**9
    assert file_older_than(midnight_ns - 1, since)
    assert not file_older_than(midnight_ns, since)
    assert not file_older_than(0, None)


def test_discovery_skips_hidden_and_output_and_applies_patterns(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    (tmp_path / "a" / "b" / "x.hpl").write_text("x")
    (tmp_path / "a" / "y.txt").write_text("y")
    (tmp_path / ".hidden").mkdir()
    (tmp_path / ".hidden" / "z.hpl").write_text("z")
    (tmp_path / "a" / ".dot.hpl").write_text("z")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "p.hpl").write_text("p")
    found = discover_files(tmp_path, exclude=[tmp_path / "out"])
    assert [p.relative_to(tmp_path).as_posix() for p in found] == ["a/b/x.hpl", "a/y.txt"]
    only_hpl = discover_files(tmp_path, ["*.hpl"], exclude=[tmp_path / "out"])
    assert [p.name for p in only_hpl] == ["x.hpl"]
    assert [p.name for p in discover_files(tmp_path, ["a/*.txt"])] == ["y.txt"]


# --------------------------------------------------------------------------------------
# ledger
# --------------------------------------------------------------------------------------


def test_ledger_save_is_atomic_and_round_trips(tmp_path):
    path = tmp_path / "ledger.json"
    ledger = load_ledger(path)
    assert ledger.units == {} and ledger.files == {}
    ledger.units["u"] = {"fingerprint": "f"}
    save_ledger(ledger, path)
    assert load_ledger(path).units == {"u": {"fingerprint": "f"}}
    assert [p.name for p in tmp_path.iterdir()] == ["ledger.json"]


def test_damaged_ledger_is_a_clear_error(tmp_path):
    path = tmp_path / "ledger.json"
    path.write_text('{"version": 1, "units": ')
    with pytest.raises(CwprocError, match="not a valid cwproc ledger"):
        load_ledger(path)


# --------------------------------------------------------------------------------------
# incremental runs (toy backend, serial)
# --------------------------------------------------------------------------------------


def test_first_run_processes_every_unit_and_second_run_nothing(tmp_path):
    paths = toy_archive(tmp_path / "in", n_days=3)
    out = tmp_path / "out"
    first = run_toy(tmp_path / "in", out)
    assert first.ok and len(first.succeeded) == 3 and first.units_total == 3
    for day in range(3):
        unit_paths = paths[2 * day : 2 * day + 2]
        product = read_product(out / f"toy_A_2024010{day + 1}_wind.nc")
        # the product holds the mean of exactly this unit's inputs
        np.testing.assert_allclose(product["wind_speed"].values, mean_of(unit_paths), rtol=1e-12)
    second = run_toy(tmp_path / "in", out)
    assert second.ok and second.processed == [] and second.units_up_to_date == 3
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert sorted(ledger.units) == ["toy_A_20240101", "toy_A_20240102", "toy_A_20240103"]
    assert ledger.failures == {}


def test_changed_or_added_input_redoes_only_its_unit(tmp_path):
    paths = toy_archive(tmp_path / "in", n_days=3)
    out = tmp_path / "out"
    run_toy(tmp_path / "in", out)
    write_toy(paths[2], "A", "2024-01-02", [100.0, 102.0], hour=0)  # day 2 changed
    new = write_toy(tmp_path / "in" / "late" / "z.txt", "A", "2024-01-03", [7.0], hour=5)
    report = run_toy(tmp_path / "in", out)
    assert sorted(o.key for o in report.processed) == ["toy_A_20240102", "toy_A_20240103"]
    assert report.units_up_to_date == 1
    product = read_product(out / "toy_A_20240103_wind.nc")
    np.testing.assert_allclose(product["wind_speed"].values, mean_of([*paths[4:6], new]))
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert len(ledger.units["toy_A_20240103"]["inputs"]) == 3


def test_touching_a_file_without_changing_it_redoes_nothing(tmp_path):
    paths = toy_archive(tmp_path / "in", n_days=2)
    out = tmp_path / "out"
    run_toy(tmp_path / "in", out)
    os.utime(paths[0], ns=(10**18, 10**18))  # new mtime: re-read, same checksum
    report = run_toy(tmp_path / "in", out)
    assert report.processed == [] and report.units_up_to_date == 2


def test_deleted_product_is_made_again(tmp_path):
    toy_archive(tmp_path / "in", n_days=2)
    out = tmp_path / "out"
    run_toy(tmp_path / "in", out)
    (out / "toy_A_20240102_wind.nc").unlink()
    report = run_toy(tmp_path / "in", out)
    assert [o.key for o in report.processed] == ["toy_A_20240102"]
    assert report.units_up_to_date == 1
    assert (out / "toy_A_20240102_wind.nc").is_file()


def test_config_change_redoes_every_unit(tmp_path):
    toy_archive(tmp_path / "in", n_days=2)
    out = tmp_path / "out"
    run_toy(tmp_path / "in", out)
    report = run_toy(tmp_path / "in", out, Config(qc=QCConfig(snr_min=0.05)))
    assert len(report.succeeded) == 2


def test_unrecognised_files_are_counted_not_errors(tmp_path):
    toy_archive(tmp_path / "in", n_days=1)
    (tmp_path / "in" / "notes.md").write_text("field notes\n")
    (tmp_path / "in" / "empty.dat").write_bytes(b"")
    report = run_toy(tmp_path / "in", tmp_path / "out")
    assert report.ok and len(report.succeeded) == 1
    assert sorted(Path(i.path).name for i in report.unrecognised) == ["empty.dat", "notes.md"]
    # unchanged unrecognised files are not opened again: their classification is cached
    again = run_toy(tmp_path / "in", tmp_path / "out")
    assert len(again.unrecognised) == 2


def test_pattern_restricts_inputs(tmp_path):
    toy_archive(tmp_path / "in", n_days=2)
    report = run_toy(tmp_path / "in", tmp_path / "out", patterns=["2024-01-02/*.txt"])
    assert report.discovered == 2
    assert [o.key for o in report.processed] == ["toy_A_20240102"]


def test_since_skips_older_units_and_does_not_read_older_files(tmp_path):
    paths = toy_archive(tmp_path / "in", n_days=3)
    old = int(dt.datetime(2024, 1, 1, 12, tzinfo=dt.UTC).timestamp()) * 10**9
    for p in paths[:2]:  # day 1 files written on day 1
        os.utime(p, ns=(old, old))
    out = tmp_path / "out"
    report = run_toy(tmp_path / "in", out, since=dt.date(2024, 1, 3))
    assert [o.key for o in report.processed] == ["toy_A_20240103"]
    # day 1 files skipped unread (mtime), day 2 unit skipped by its data date
    assert report.files_before_since == 2 and report.units_before_since == 1
    assert set(load_ledger(out / STATE_DIR / "ledger.json").files) == {
        os.fspath(p) for p in paths[2:]
    }


def test_files_still_being_written_wait_for_a_later_run(tmp_path):
    paths = toy_archive(tmp_path / "in", n_days=1)
    hour_ago = time.time_ns() - 3600 * 10**9
    os.utime(paths[0], ns=(hour_ago, hour_ago))  # paths[1] was just written
    out = tmp_path / "out"
    first = run_toy(tmp_path / "in", out, min_age_s=600)
    assert first.files_too_new == 1
    product = read_product(out / "toy_A_20240101_wind.nc")
    np.testing.assert_allclose(product["wind_speed"].values, mean_of(paths[:1]), rtol=1e-12)
    os.utime(paths[1], ns=(hour_ago, hour_ago))  # the instrument has closed it
    second = run_toy(tmp_path / "in", out, min_age_s=600)
    assert second.files_too_new == 0 and len(second.succeeded) == 1
    product = read_product(out / "toy_A_20240101_wind.nc")
    np.testing.assert_allclose(product["wind_speed"].values, mean_of(paths), rtol=1e-12)


def test_output_inside_input_is_not_read_back(tmp_path):
    toy_archive(tmp_path, n_days=1)
    report = run_toy(tmp_path, tmp_path / "products")
    again = run_toy(tmp_path, tmp_path / "products")
    assert report.discovered == again.discovered == 2
    assert again.processed == []


def test_a_reader_bug_fails_that_file_only(tmp_path, monkeypatch):
    """classify_file (the real one) turns an unexpected reader exception into a failure."""
    import cwproc.batch.worker

    good = tmp_path / "in" / "a.hpl"
    good.parent.mkdir()
    good.write_text("Filename:\tVAD_1_20240101_000000.hpl\n")

    def broken_reader(path, config, *, identify_only=False, checksum=True):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(cwproc.batch.worker, "read_input", broken_reader)
    report = run_batch(tmp_path / "in", tmp_path / "out", Config())
    assert [f.error for f in report.file_failures] == [
        f"{good}: internal error of the hpl reader ZeroDivisionError: division by zero"
    ]
    assert report.processed == [] and not report.ok


def test_missing_input_directory_is_a_clear_error(tmp_path):
    with pytest.raises(CwprocError, match="input directory does not exist"):
        run_toy(tmp_path / "nope", tmp_path / "out")


def test_output_directory_equal_to_input_is_refused(tmp_path):
    toy_archive(tmp_path / "in", n_days=1)
    with pytest.raises(CwprocError, match="must not be the input directory"):
        run_toy(tmp_path / "in", tmp_path / "in" / "2024-01-01" / "..")
    assert not (tmp_path / "in" / STATE_DIR).exists()


# --------------------------------------------------------------------------------------
# lock
# --------------------------------------------------------------------------------------


def test_second_holder_gives_up_at_once_naming_the_first(tmp_path):
    with output_lock(tmp_path) as stale:
        assert stale == ""
        t0 = time.monotonic()
        with pytest.raises(LockBusyError) as info, output_lock(tmp_path):
            pass
        assert time.monotonic() - t0 < 1.0
        assert f"pid={os.getpid()}" in str(info.value)
    # released cleanly: the next holder finds no stale text
    with output_lock(tmp_path) as stale:
        assert stale == ""


def test_waiting_holder_gets_the_lock_when_the_first_releases(tmp_path):
    release = threading.Event()
    held = threading.Event()

    def first() -> None:
        with output_lock(tmp_path):
            held.set()
            release.wait(5)

    thread = threading.Thread(target=first)
    thread.start()
    held.wait(5)
    threading.Timer(0.3, release.set).start()
    t0 = time.monotonic()
    with output_lock(tmp_path, wait_s=5.0, poll_s=0.05) as stale:
        waited = time.monotonic() - t0
        assert stale == ""
    thread.join()
    assert 0.2 < waited < 5.0


def test_lock_of_a_killed_process_is_taken_over(tmp_path):
    code = (
        "import sys, time\n"
        "from cwproc.batch import output_lock\n"
        "with output_lock(sys.argv[1]):\n"
        "    print('locked', flush=True)\n"
        "    time.sleep(60)\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout.readline().strip() == "locked"
        with pytest.raises(LockBusyError), output_lock(tmp_path):
            pass
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    with output_lock(tmp_path) as stale:
        assert f"pid={proc.pid}" in stale
    assert json.loads(json.dumps(stale))  # plain text, printable in a message


# --------------------------------------------------------------------------------------
# the real pipeline on synthetic Stream Line files with a known wind
# --------------------------------------------------------------------------------------

#: what ``pipeline.process_scans`` imports (structure/epsilon even with turbulence off)
_PIPELINE_MODULES = (
    "cwproc.io.halo",
    "cwproc.io.scan_join",
    "cwproc.stages.qc",
    "cwproc.stages.vad",
    "cwproc.stages.structure",
    "cwproc.stages.epsilon",
)


def _missing_pipeline_modules() -> list[str]:
    return [m for m in _PIPELINE_MODULES if importlib.util.find_spec(m) is None]


def synthetic_vad_scans(day: str, hour: int, u: float, v: float, w: float = 0.0):
    """A canonical scan dataset: 3 rotations of 36 rays at 60 deg elevation, exact V_r.

    V_r = w sin(phi) + cos(phi) (u sin(theta) + v cos(theta)), Smalikho (2020), eq. 1.
    """
    n_rot, n_az, n_gate = 3, 36, 8
    az = np.tile(np.arange(n_az) * 10.0, n_rot)
    el = np.full(az.size, 60.0)
    t0 = np.datetime64(f"{day}T{hour:02d}:00:00", "ns")
    times = t0 + (np.arange(az.size) * 1.0e9).astype("timedelta64[ns]")
    phi, theta = np.deg2rad(el), np.deg2rad(az)
    vr = w * np.sin(phi) + np.cos(phi) * (u * np.sin(theta) + v * np.cos(theta))
    rng = np.arange(n_gate) * 30.0 + 15.0
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), np.repeat(vr[:, None], n_gate, axis=1)),
            "snr": (("ray", "range"), np.full((az.size, n_gate), 1.0)),
            "beta": (("ray", "range"), np.full((az.size, n_gate), 1e-6)),
        },
        coords={
            "time": ("ray", times),
            "azimuth": ("ray", az),
            "elevation": ("ray", el),
            "range": ("range", rng),
            "scan": ("ray", np.repeat(np.arange(n_rot), n_az).astype(np.int64)),
        },
        attrs={
            "instrument": "Halo Photonics Stream Line",
            "instrument_kind": "streamline",
            "system_id": "99",
            "scan_type": "VAD",
            "gate_length_m": 30.0,
            "homodyne": 0,
            "points_per_gate": 10,
            "pulses_per_ray": 10000,
            "focus_range_m": 65535.0,
            "velocity_resolution_m_s": 0.0382,
            "source_files": [],
        },
    )


def wind_only_config() -> Config:
    text = (
        Config().to_toml().replace("[turbulence]\nenabled = true", "[turbulence]\nenabled = false")
    )
    return config_from_toml(text, source="<test wind only>")


@pytest.mark.skipif(
    bool(_missing_pipeline_modules()),
    reason=f"pipeline modules not built yet: {', '.join(_missing_pipeline_modules())}",
)
def test_real_pipeline_batch_recovers_the_wind_and_is_incremental(tmp_path):
    from cwproc.io.halo import write_hpl

    truth = {"2024-03-01": (3.0, -4.0), "2024-03-02": (-6.0, 2.5)}
    for day, (u, v) in truth.items():
        for hour in (10, 11):
            folder = tmp_path / "in" / day
            folder.mkdir(parents=True, exist_ok=True)
            write_hpl(
                synthetic_vad_scans(day, hour, u, v),
                folder / f"VAD_99_{day.replace('-', '')}_{hour}0000.hpl",
            )
    out = tmp_path / "out"
    config = wind_only_config()
    report = run_batch(tmp_path / "in", out, config)
    assert report.ok, report.failure_lines()
    assert len(report.succeeded) == 2
    for day, (u, v) in truth.items():
        (product_path,) = out.glob(f"*_99_{day.replace('-', '')}_wind.nc")
        wind = read_product(product_path)
        # exact synthetic radial velocities, quantised to the file's printed decimals
        np.testing.assert_allclose(wind["u"].values, u, atol=0.01)
        np.testing.assert_allclose(wind["v"].values, v, atol=0.01)
    again = run_batch(tmp_path / "in", out, config)
    assert again.processed == [] and again.units_up_to_date == 2
    # the same units and the same products as `cwproc retrieve` on the same files
    from cwproc.pipeline import retrieve_files

    inputs = sorted((tmp_path / "in").absolute().rglob("*.hpl"))
    retrieved = retrieve_files(inputs, tmp_path / "retrieve", config)
    assert retrieved.ok, retrieved.failures
    assert sorted(p.name for p in retrieved.written) == sorted(p.name for p in out.glob("*.nc"))
    dates = {"history", "date_created", "date_modified", "date_issued", "date_metadata_modified"}
    dates.add("file_uuid")  # ACTRIS/Cloudnet: every file written has its own
    for path in retrieved.written:
        a, b = read_product(path), read_product(out / path.name)
        xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))
        assert {k: v for k, v in a.attrs.items() if k not in dates} == {
            k: v for k, v in b.attrs.items() if k not in dates
        }


def test_deleted_files_leave_the_ledger_and_their_failures_with_them(tmp_path):
    paths = toy_archive(tmp_path / "in", n_days=2)
    bad = write_toy(tmp_path / "in" / "bad.txt", "A", "2024-01-01", [1.0])
    bad.write_text(bad.read_text() + "oops\n")
    out = tmp_path / "out"
    assert not run_toy(tmp_path / "in", out).ok
    bad.unlink()
    paths[0].unlink()
    report = run_toy(tmp_path / "in", out)
    assert report.ok and [o.key for o in report.processed] == ["toy_A_20240101"]
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert set(ledger.files) == {os.fspath(p) for p in paths[1:]}
    assert ledger.failures == {}
    assert ledger.units["toy_A_20240101"]["inputs"] == {os.fspath(paths[1]): sha256_file(paths[1])}


def test_unlistable_folder_is_reported_not_skipped_silently(tmp_path, monkeypatch):
    toy_archive(tmp_path / "in", n_days=1)
    locked = tmp_path / "in" / "locked"
    real_walk = os.walk

    def walk_with_a_denied_folder(top, onerror=None, **kwargs):
        onerror(PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(locked)))
        yield from real_walk(top, onerror=onerror, **kwargs)

    monkeypatch.setattr(os, "walk", walk_with_a_denied_folder)
    report = run_toy(tmp_path / "in", tmp_path / "out")
    assert not report.ok and len(report.succeeded) == 1
    assert report.failure_lines() == [f"{locked}: cannot list folder: Permission denied"]


_ops = st.lists(
    st.one_of(
        st.tuples(st.just("add"), st.integers(1, 3), st.integers(0, 3), st.integers(1, 5)),
        st.tuples(st.just("change"), st.integers(0, 20), st.integers(1, 5)),
        st.tuples(st.just("delete"), st.integers(0, 20)),
        st.tuples(st.just("run")),
    ),
    min_size=1,
    max_size=12,
)


@settings(
    max_examples=15,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(ops=_ops, seed=st.integers(0, 2**16))
def test_any_history_of_edits_ends_with_every_product_matching_its_inputs(ops, seed):
    """Idempotency as a property: after any sequence of added, changed and deleted files
    and runs, one more run leaves every unit's product equal to the mean of exactly its
    current inputs, and a run after that processes nothing."""
    rng = np.random.default_rng(seed)
    with tempfile.TemporaryDirectory() as tmp:
        inputs, out = Path(tmp) / "in", Path(tmp) / "out"
        inputs.mkdir()
        for op in ops:
            files = sorted(inputs.rglob("*.txt"))
            if op[0] == "add":
                _, day, hour, n = op
                day_s = f"2024-01-{day:02d}"
                write_toy(inputs / day_s / f"h{hour}.txt", "P", day_s, rng.normal(size=n), hour)
            elif op[0] == "change" and files:
                path = files[op[1] % len(files)]
                header = path.read_text().splitlines()[1].split()[1]  # time=...
                day_s, hour = header[5:15], int(header[16:18])
                write_toy(path, "P", day_s, rng.normal(size=op[2]) + 10, hour)
            elif op[0] == "delete" and files:
                files[op[1] % len(files)].unlink()
            elif op[0] == "run":
                assert run_toy(inputs, out).ok
        assert run_toy(inputs, out).ok
        by_unit: dict[str, list[Path]] = {}
        for path in inputs.rglob("*.txt"):
            by_unit.setdefault(f"toy_P_{path.parent.name.replace('-', '')}", []).append(path)
        for key, paths in by_unit.items():
            product = read_product(out / f"{key}_wind.nc")
            np.testing.assert_allclose(product["wind_speed"].values, mean_of(paths), rtol=1e-12)
        again = run_toy(inputs, out)
        assert again.processed == [] and again.units_up_to_date == len(by_unit)


@pytest.mark.skipif(
    importlib.util.find_spec("cwproc.io.halo") is None,
    reason="the Halo reader cwproc.io.halo is not built yet",
)
def test_input_changed_between_planning_and_processing_fails_the_unit(tmp_path):
    from cwproc.batch import classify_file, plan_units, process_unit_task
    from cwproc.io.halo import write_hpl

    path = tmp_path / "VAD_99_20240301_100000.hpl"
    write_hpl(synthetic_vad_scans("2024-03-01", 10, 1.0, 1.0), path)
    config = wind_only_config()
    info = classify_file(str(path), config.to_toml(), config.source)
    assert info.status == "ok", info.error
    ((task, start),) = plan_units([info], config, tmp_path / "out")
    assert start == "2024-03-01T10:00:00Z"
    write_hpl(synthetic_vad_scans("2024-03-01", 10, 2.0, 1.0), path)  # rewritten meanwhile
    outcome = process_unit_task(task)
    assert outcome.error == (
        f"{path}: changed while the run was going on; "
        f"unit {task.key} will be redone by the next run"
    )
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(
    bool(_missing_pipeline_modules()),
    reason=f"pipeline modules not built yet: {', '.join(_missing_pipeline_modules())}",
)
def test_process_pool_gives_the_products_of_a_serial_run(tmp_path):
    """--workers N (a local process pool): same units, same products, driver-only ledger."""
    from cwproc.batch import close_client, load_ledger, local_pool
    from cwproc.io.halo import write_hpl

    for day, (u, v) in {"2024-03-01": (3.0, -4.0), "2024-03-02": (-6.0, 2.5)}.items():
        folder = tmp_path / "in" / day
        folder.mkdir(parents=True)
        write_hpl(synthetic_vad_scans(day, 10, u, v), folder / f"VAD_99_{day.replace('-', '')}.hpl")
    config = wind_only_config()
    serial = run_batch(tmp_path / "in", tmp_path / "serial", config)
    pool = local_pool(2)
    try:
        pooled = run_batch(tmp_path / "in", tmp_path / "pool", config, client=pool)
    finally:
        close_client(pool)
    assert serial.ok and pooled.ok, pooled.failure_lines()
    assert len({o.pid for o in pooled.processed}) >= 1
    assert all(o.pid != os.getpid() for o in pooled.processed)
    names = sorted(p.name for p in (tmp_path / "serial").glob("*.nc"))
    assert names and names == sorted(p.name for p in (tmp_path / "pool").glob("*.nc"))
    for name in names:
        a = read_product(tmp_path / "serial" / name)
        b = read_product(tmp_path / "pool" / name)
        xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))
    ledger = load_ledger(tmp_path / "pool" / ".cwproc" / "ledger.json")
    assert len(ledger.units) == 2


def test_ledger_save_appends_only_the_change(tmp_path):
    """After the first snapshot a save costs the change, not the ledger (issue 17.8)."""
    from cwproc.batch import journal_path

    path = tmp_path / "ledger.json"
    ledger = load_ledger(path)
    for i in range(2000):
        ledger.files[f"/a/{i}"] = {"size": i}
    save_ledger(ledger, path)
    snapshot = path.read_bytes()
    ledger.units["u1"] = {"fingerprint": "f1"}
    ledger.failures.pop("nothing", None)
    save_ledger(ledger, path)
    assert path.read_bytes() == snapshot  # the snapshot is not rewritten
    lines = journal_path(path).read_text().splitlines()
    assert len(lines) == 1 and json.loads(lines[0])["key"] == "u1"
    del ledger.files["/a/0"]
    save_ledger(ledger, path)
    again = load_ledger(path)
    assert again.units == {"u1": {"fingerprint": "f1"}}
    assert "/a/0" not in again.files and len(again.files) == 1999
    save_ledger(again, path, compact=True)
    assert not journal_path(path).exists()
    assert load_ledger(path).units == again.units


def test_torn_journal_line_of_a_killed_run_is_ignored(tmp_path):
    from cwproc.batch import journal_path

    path = tmp_path / "ledger.json"
    ledger = load_ledger(path)
    ledger.units["a"] = {"fingerprint": "1"}
    save_ledger(ledger, path)
    ledger.units["b"] = {"fingerprint": "2"}
    save_ledger(ledger, path)
    with open(journal_path(path), "ab") as fh:
        fh.write(b'{"table": "units", "key": "c", "val')  # killed mid-write
    assert set(load_ledger(path).units) == {"a", "b"}


def test_a_run_appends_its_changes_and_the_journal_never_outgrows_the_ledger(tmp_path):
    """The end of a run no longer rewrites the snapshot (issue 34.7): a second run that
    redoes one unit leaves ``ledger.json`` byte for byte and appends its change; the
    ledger loads complete, and compaction keeps the journal no longer than the ledger."""
    from cwproc.batch import journal_path
    from cwproc.batch.state import COMPACT_MIN_LINES, needs_compaction

    toy_archive(tmp_path / "in", n_days=3)
    out = tmp_path / "out"
    report = run_toy(tmp_path / "in", out)
    assert report.ok
    ledger_path = out / STATE_DIR / "ledger.json"
    snapshot = ledger_path.read_bytes()
    ledger = load_ledger(ledger_path)
    assert len(ledger.units) == len(report.processed)
    product = Path(next(iter(ledger.units.values()))["products"][0])
    product.unlink()  # made again by the next run
    again = run_toy(tmp_path / "in", out)
    assert again.ok and len(again.processed) == 1
    assert ledger_path.read_bytes() == snapshot
    assert journal_path(ledger_path).exists()
    assert load_ledger(ledger_path).units.keys() == ledger.units.keys()
    big = load_ledger(tmp_path / "big.json")
    for i in range(3 * COMPACT_MIN_LINES):
        big.files[f"/f{i}"] = {"size": i}
        save_ledger(big, tmp_path / "big.json")
        assert big.journal_lines <= max(COMPACT_MIN_LINES, big.size() / 4)
    assert not needs_compaction(big)


def test_two_loggers_of_one_day_are_two_units_and_same_named_records_too(tmp_path):
    """Sonic units are keyed by station, wind records by folder too (issue 17.2)."""
    from cwproc.io import Format
    from cwproc.pipeline import InputFile, group_units

    t = np.array(["2012-06-07T12:00"], dtype="datetime64[ns]")

    def sonic(station: str, folder: str) -> InputFile:
        ds = xr.Dataset(coords={"time": t}, attrs={"toa5_station": station})
        return InputFile(Path(tmp_path / folder / "TOA5_x.dat"), Format.TOA5, "0", ds)

    notes: list[str] = []
    units = group_units([sonic("6843", "a"), sonic("7777", "a"), sonic("6843", "b")], notes)
    # one station name in two folders: two loggers (issue 34.2), kept apart and noted
    assert sorted(u.key for u in units) == [
        "toa5_6843-a_20120607",
        "toa5_6843-b_20120607",
        "toa5_7777_20120607",
    ]
    assert [len(u.inputs) for u in units] == [1, 1, 1]
    assert len(notes) == 1 and "differ in folder" in notes[0]
    rec = xr.Dataset(coords={"time": t})
    records = [
        InputFile(Path(tmp_path / f / "Wind10_1.ZPH.csv"), Format.ZEPHIR_CSV, "0", rec)
        for f in ("site1", "site2")
    ]
    keys = sorted(u.key for u in group_units(records))
    assert keys == ["site1_Wind10_1.ZPH", "site2_Wind10_1.ZPH"]
