"""Meteo-2 text layout (cwproc's own, docs/sonic.md): reader, writer, data problems."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.errors import InputFileError
from cwproc.io import Format, detect_format
from cwproc.io.meteo2 import read_meteo2, write_meteo2
from cwproc.io.sonic_samples import _spike_mask_everywhere, measure_sampling_rate, spike_mask
from cwproc.sim.sonic import METEO2_RATE_HZ, simulate_sonic_dataset

FIXTURE_CHECK = HealthCheck.function_scoped_fixture


@pytest.fixture(scope="module")
def sim() -> xr.Dataset:
    return simulate_sonic_dataset(hours=0.1, sf_type=2, seed=21)


@pytest.fixture
def m2file(tmp_path, sim):
    p = tmp_path / "m2.txt"
    write_meteo2(sim, p, station="test")
    return p


def test_round_trip_and_format_detection(m2file, sim):
    assert detect_format(m2file) == Format.METEO2
    ds = read_meteo2(m2file)
    assert ds.sizes["time"] == sim.sizes["time"]
    np.testing.assert_allclose(ds["u"].values, sim["u"].values, atol=5e-4)
    np.testing.assert_allclose(ds["temperature"].values, sim["temperature"].values, atol=5e-4)
    # millisecond stamps of a 10.7 Hz clock: the measured rate is 10.7 Hz within 1e-4
    assert ds.attrs["sampling_rate_hz"] == pytest.approx(METEO2_RATE_HZ, rel=1e-4)
    assert ds.attrs["meteo2_station"] == "test"
    assert ds.attrs["warnings"] == []


def test_measured_rate_ignores_gaps():
    t = np.rint(np.arange(1000) * 1e9 / 10.7).astype(np.int64)
    t = np.delete(t, np.arange(300, 400))
    assert measure_sampling_rate(t) == pytest.approx(10.7, rel=1e-6)


def _lines(p):
    return p.read_text().splitlines(keepends=True)


def test_gaps_duplicates_order_spikes_and_nan_are_reported(tmp_path, m2file):
    lines = _lines(m2file)
    head, data = lines[:6], lines[6:]
    data[100], data[101] = data[101], data[100]
    data.insert(200, data[200])
    del data[400:450]
    f = data[600].split(",")
    f[1] = "30.000"
    data[600] = ",".join(f)
    f = data[700].split(",")
    f[2] = "NaN"
    data[700] = ",".join(f)
    p = tmp_path / "bad.txt"
    p.write_text("".join(head + data))
    ds = read_meteo2(p)
    a = ds.attrs
    assert (a["n_out_of_order"], a["n_duplicates"], a["n_gaps"]) == (1, 1, 1)
    assert a["gap_seconds"] == pytest.approx(50 / METEO2_RATE_HZ, abs=0.002)
    assert a["n_spikes"] == 1 and a["n_not_finite"] == 1
    assert len(a["warnings"]) == 5
    # flagged, never removed or interpolated
    assert (ds["u"].values == 30.0).sum() == 1
    assert ds["sample_flag"].values[ds["u"].values == 30.0][0] == 2
    assert np.isnan(ds["v"].values).sum() == 1


def test_configurable_layout(tmp_path, sim):
    t = sim["time"].values[:50].astype("datetime64[ns]").astype(np.int64) / 1e9 + 7 * 3600
    body = "\n".join(
        f"{tt:.3f};{u:.3f};{v:.3f};{w:.3f}"
        for tt, u, v, w in zip(t, sim["u"].values, sim["v"].values, sim["w"].values, strict=False)
    )
    p = tmp_path / "other.txt"
    p.write_text("% exported\nepoch;vx;vy;vz\n" + body + "\n")
    ds = read_meteo2(
        p,
        delimiter=";",
        comment="%",
        time_format="epoch",
        utc_offset_hours=7,
        columns={"time": "epoch", "u": "vx", "v": "vy", "w": "vz"},
    )
    assert ds.sizes["time"] == 50
    assert abs(ds["time"].values[0] - sim["time"].values[0]) <= np.timedelta64(1, "ms")
    assert np.all(np.isnan(ds["temperature"].values))


@pytest.mark.parametrize(
    ("index", "mutate", "match"),
    [
        (10, lambda s: s.replace(",", ",x", 1), "not a number"),
        (12, lambda s: "2014-13-01 00:00:00.000" + s[23:], "bad time stamp"),
        (14, lambda s: s.rstrip("\n") + ",1,2\n", "malformed"),
        (15, lambda s: "\n", "empty data line"),
    ],
)
def test_damaged_lines_are_named(tmp_path, m2file, index, mutate, match):
    lines = _lines(m2file)
    lines[index - 1] = mutate(lines[index - 1])
    p = tmp_path / "d.txt"
    p.write_text("".join(lines))
    with pytest.raises(InputFileError, match=match) as err:
        read_meteo2(p)
    assert err.value.line == index


def test_header_and_option_errors(tmp_path, m2file):
    lines = _lines(m2file)
    p = tmp_path / "h.txt"
    p.write_text("".join(lines[:5]))
    with pytest.raises(InputFileError, match="header"):
        read_meteo2(p)
    p.write_text("".join(lines[:6]))
    with pytest.raises(InputFileError, match="no data records"):
        read_meteo2(p)
    p.write_text("".join(lines[:5]) + lines[5].replace("u,", "uu,") + "".join(lines[6:20]))
    with pytest.raises(InputFileError, match="'u'") as err:
        read_meteo2(p)
    assert err.value.line == 6
    with pytest.raises(InputFileError, match="time_format"):
        read_meteo2(m2file, time_format="julian")
    with pytest.raises(InputFileError, match="unknown reader option"):
        read_meteo2(m2file, sep=";")


@settings(max_examples=40, deadline=None, suppress_health_check=[FIXTURE_CHECK])
@given(data=st.data())
def test_mutated_meteo2_gives_dataset_or_input_file_error(tmp_path, m2file, data):
    blob = bytearray(b"".join(line.encode() for line in _lines(m2file)[:80]))
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(blob) - 1))
        blob[i] = data.draw(st.sampled_from(list(b"0123456789,.:-# \nNaTe\x00")))
    p = tmp_path / "mut.txt"
    p.write_bytes(bytes(blob[: data.draw(st.integers(0, len(blob)))]))
    try:
        ds = read_meteo2(p)
    except InputFileError:
        return
    assert isinstance(ds, xr.Dataset) and ds.sizes["time"] > 0


@pytest.mark.parametrize(
    "cut", ["2024-06-01", "2024-06-01T12:00:00.9", "2024-06-01T12:00:00.930,4.1"]
)
def test_last_line_cut_while_written_is_dropped_not_read_as_midnight(tmp_path, cut):
    """A Meteo-2 file cut in its last line (still being written, a full disk) gave a sample
    at 00:00 of the day, 12 h before the file's first record (issue 17.4, found by
    tests/test_damaged_inputs.py)."""
    from pathlib import Path

    sample = Path(__file__).parents[2] / "sample_data/sonic/meteo2_2024_06_01_1200.txt"
    lines = sample.read_text().splitlines(keepends=True)[:16]
    path = tmp_path / "meteo2_cut.txt"
    path.write_text("".join(lines) + cut)
    ds = read_meteo2(path)
    assert ds.sizes["time"] == 10  # the 10 complete records
    assert ds["time"].values.min() == np.datetime64("2024-06-01T12:00:00")
    assert any("line 17: last line cut short" in w for w in ds.attrs["warnings"])
    # a complete last line without an end of line is data
    path.write_text("".join(lines[:-1]) + lines[-1].rstrip("\n"))
    assert read_meteo2(path).sizes["time"] == 10


def test_stray_stamp_of_a_damaged_record_is_dropped():
    """A flipped byte in one TOB1 SECONDS field gave a sample 20 years before the file's
    first record (found by tests/test_damaged_inputs.py): a stamp far from both of its
    neighbours, which agree with each other, is dropped and reported."""
    from cwproc.io.sonic_samples import sonic_dataset, stray_stamps

    t = np.datetime64("2024-06-01T12:00", "ns") + np.arange(100) * np.timedelta64(100, "ms")
    for i in (0, 40, 99):
        bad = t.copy()
        bad[i] = np.datetime64("2004-04-20T06:50:25", "ns")
        assert np.flatnonzero(stray_stamps(bad.astype(np.int64))).tolist() == [i]
        x = np.ones(100)
        ds = sonic_dataset(
            "f.dat", bad, {"u": x, "v": x, "w": x}, x, np.zeros(100), instrument="i", frame="f"
        )
        assert ds.sizes["time"] == 99 and ds["time"].values.min() >= t[0]
        # refused as out of the file's sequence (issue 34.3), or as a stray stamp
        assert any(
            "far from both neighbours" in w or "breaks the file's sequence" in w
            for w in ds.attrs["warnings"]
        )
    # a gap, a restart and a swapped pair are data, not stray stamps
    gap = np.concatenate([t[:50], t[50:] + np.timedelta64(1, "h")])
    swapped = t.copy()
    swapped[[10, 11]] = swapped[[11, 10]]
    for ok in (gap, np.concatenate([t[:50], t[:50]]), swapped):
        assert not stray_stamps(ok.astype(np.int64)).any()


def test_spike_mask_equals_the_running_median_everywhere():
    """The candidate-only median (window range >= limit) flags exactly the samples the
    running median at every sample flags: random walks with spikes, gaps, constants."""
    rng = np.random.default_rng(3)
    for trial in range(60):
        n = int(rng.integers(5, 3000))
        x = np.cumsum(rng.normal(size=n)) * 0.1 + rng.normal(size=n)
        k = int(rng.integers(0, 20))
        x[rng.integers(0, n, k)] += rng.normal(size=k) * rng.choice([1.0, 10.0, 100.0])
        if trial % 3 == 0:
            x[rng.integers(0, n, int(rng.integers(0, n // 3 + 1)))] = np.nan
        if trial % 17 == 0:
            x[:] = 1.0
        width, scale_width = int(rng.integers(1, 30)), int(rng.integers(3, 700))
        threshold = float(rng.choice([2.0, 3.0, 6.0]))
        fast = spike_mask(x, width, threshold, scale_width)
        full = _spike_mask_everywhere(pd.Series(x), max(width, 3) | 1, threshold, scale_width)
        np.testing.assert_array_equal(fast, full)
