"""How often ``cwproc batch`` reads its ``.hpl`` inputs on a first run (issue 15).

Classification takes a Stream Line file's unit and first time from its header (and
checksums its bytes); only the unit run parses its data. The ledger records are those
of the old classification, which read every file whole.
"""

from __future__ import annotations

import os
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import cwproc.io.halo as halo
import cwproc.io.halo_files as halo_files
from cwproc.batch import STATE_DIR, FileInfo, classify_file, load_ledger, run_batch
from cwproc.config import Config
from cwproc.errors import InputFileError
from cwproc.io.netcdf import read_product, sha256_file
from cwproc.pipeline import read_input, unit_key

REPO = Path(__file__).resolve().parents[1]
STREAMLINE = REPO / "sample_data" / "streamline"
REAL_HPL = REPO.parent / "shared" / "real_data" / "hpl"


def whole_read_classification(path: Path, config: Config) -> tuple[str, str, str, str, str]:
    """(format, kind, unit, start, sha256) as classification gave them when it read the
    file whole with the format's reader (before issue 15)."""
    item = read_input(path, config)
    kind, key = unit_key(item)
    t = item.dataset["time"].values
    start = str(t[~np.isnat(t)].min().astype("datetime64[s]")) + "Z"
    return item.format.value, kind, key, start, item.sha256


def record(info: FileInfo) -> tuple[str, str, str, str, str]:
    return info.format, info.kind, info.unit, info.start, info.sha256


@pytest.fixture
def body_reads(monkeypatch) -> Counter:
    """Counts of each path whose header and data lines were read (the .hpl body parse of
    both ``read_hpl`` and the day streamer)."""
    counts: Counter = Counter()
    original = halo.read_header_body_offset

    def counting(path, *rest):
        counts[os.fspath(path)] += 1
        return original(path, *rest)

    monkeypatch.setattr(halo, "read_header_body_offset", counting)
    monkeypatch.setattr(halo_files, "read_header_body_offset", counting)
    return counts


def test_first_batch_run_parses_each_hpl_file_once(tmp_path, body_reads):
    inputs = tmp_path / "in"
    shutil.copytree(STREAMLINE, inputs)
    paths = sorted(inputs.glob("*.hpl"))
    assert len(paths) == 2
    config = Config()
    expected = {os.fspath(p): whole_read_classification(p, config) for p in paths}
    body_reads.clear()

    report = run_batch(inputs, tmp_path / "out", config)

    assert report.ok and len(report.succeeded) == 1
    assert body_reads == Counter({os.fspath(p): 1 for p in paths})
    ledger = load_ledger(tmp_path / "out" / STATE_DIR / "ledger.json")
    for path, (fmt, kind, unit, start, sha) in expected.items():
        entry = ledger.files[path]
        assert (entry["format"], entry["kind"], entry["unit"], entry["start"]) == (
            fmt,
            kind,
            unit,
            start,
        )
        assert entry["sha256"] == sha == sha256_file(path)
    (key,) = ledger.units
    assert ledger.units[key]["inputs"] == {p: v[4] for p, v in expected.items()}


@pytest.mark.skipif(not REAL_HPL.is_dir(), reason="needs ../shared/real_data")
def test_header_classification_equals_whole_read_on_real_files():
    config = Config()
    checked = 0
    for path in sorted(REAL_HPL.glob("*.hpl")):
        try:
            expected = whole_read_classification(path, config)
        except Exception:  # the damaged samples: covered below
            continue
        info = classify_file(os.fspath(path), config.to_toml())
        assert info.status == "ok", info.error
        assert record(info) == expected, path.name
        checked += 1
    assert checked >= 3


def test_hpl_damaged_beyond_its_header_is_a_file_failure_as_before(tmp_path, body_reads):
    inputs, out = tmp_path / "in", tmp_path / "out"
    shutil.copytree(STREAMLINE, inputs)
    good, bad = sorted(inputs.glob("*.hpl"))
    raw = bad.read_bytes().split(b"\n")
    line = len(raw) // 2  # a data line well past the header
    raw[line] = b"  12.5e 0.1"
    bad.write_bytes(b"\n".join(raw))

    with pytest.raises(InputFileError) as whole_read:  # what classification said before
        read_input(bad, Config())

    first = run_batch(inputs, out, Config())
    assert [f.path for f in first.file_failures] == [os.fspath(bad)]
    assert first.failure_lines() == [str(whole_read.value)]
    assert str(whole_read.value).startswith(f"{bad}:{line + 1}: ")
    assert len(first.succeeded) == 1 and not first.failed
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert ledger.files[os.fspath(bad)]["status"] == "error"
    assert ledger.failures[os.fspath(bad)]["attempts"] == 1
    (key,) = ledger.units
    assert ledger.units[key]["inputs"] == {os.fspath(good): sha256_file(good)}
    products = sorted(out.glob("*.nc"))
    # the same products as a run on the good file alone
    alone_in, alone_out = tmp_path / "alone", tmp_path / "alone_out"
    alone_in.mkdir()
    shutil.copy2(good, alone_in / good.name)
    run_batch(alone_in, alone_out, Config())
    for product in products:
        made, reference = read_product(product), read_product(alone_out / product.name)
        for name in reference.data_vars:
            assert made[name].equals(reference[name]), name

    second = run_batch(inputs, out, Config())
    assert second.processed == [] and second.units_up_to_date == 1
    assert [f.path for f in second.file_failures] == [os.fspath(bad)]
    assert load_ledger(out / STATE_DIR / "ledger.json").failures[os.fspath(bad)]["attempts"] == 2


def test_all_inputs_of_a_unit_damaged_leave_no_unit(tmp_path):
    inputs, out = tmp_path / "in", tmp_path / "out"
    shutil.copytree(STREAMLINE, inputs)
    for path in inputs.glob("*.hpl"):
        raw = path.read_bytes().split(b"\n")
        raw[len(raw) // 2] = b"  12.5e 0.1"
        path.write_bytes(b"\n".join(raw))
    report = run_batch(inputs, out, Config())
    assert len(report.file_failures) == 2 and report.processed == []
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert ledger.units == {} and set(ledger.failures) == {
        os.fspath(p) for p in inputs.glob("*.hpl")
    }
