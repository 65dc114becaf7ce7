"""``cwproc simulate``: any number of gates, the geometry options, progress on terminals only."""

from __future__ import annotations

import dataclasses
import io

import numpy as np
import pytest
from click.testing import CliRunner

from cwproc import progress
from cwproc.cli import main
from cwproc.physics.geometry import wind_components


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def test_any_number_of_gates_one_file_per_vad_and_the_wind_at_the_far_gates(tmp_path, monkeypatch):
    monkeypatch.setattr(progress, "DELAY_S", 0.0)  # a bar would show at once
    res = run(
        "simulate", "lidar", "-o", str(tmp_path), "--hours", "0.05", "--gates", "110",
        "--gate-length", "24", "--scan-period", "45", "--scans-per-file", "1", "--wind", "8",
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    files = sorted((tmp_path / "data").glob("*.hpl"))
    assert len(files) == 4  # 180 s of 45-s scans, one per file
    # no progress bar: CliRunner's stderr is not a terminal (as under cron)
    assert "%|" not in res.output and "file/s" not in res.output
    from cwproc.io.halo import read_hpl

    ds = read_hpl(files[-1])
    assert ds.sizes["range"] == 110 and ds.sizes["ray"] == 180
    np.testing.assert_allclose(ds["range"].values, (np.arange(110) + 0.5) * 24.0)
    t = ds["time"].values
    # 180 rays in 45 s (the file's times are written to 1e-8 h, 36 us)
    assert (t[-1] - t[0]) / np.timedelta64(1, "s") == pytest.approx(45.0 * 179 / 180, abs=1e-4)
    # the VAD sine at the far gates (2.6 km) carries the wind of the command
    el = np.deg2rad(35.3)
    az = np.deg2rad(ds["azimuth"].values)
    design = np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.ones_like(az)], 1)
    fit, *_ = np.linalg.lstsq(design, ds["radial_velocity"].values[:, 100:], rcond=None)
    u, v = wind_components(8.0, 240.0)
    np.testing.assert_allclose(fit[:2].mean(axis=1), [u, v], atol=0.5)


def test_geometry_options_are_refused_where_they_would_be_ignored(tmp_path):
    res = CliRunner().invoke(
        main, ["simulate", "lidar", "-o", str(tmp_path), "--instrument", "cw", "--gates", "50"]
    )
    assert res.exit_code == 2 and "--gates" in res.output


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_series_shows_its_files_on_a_terminal(tmp_path, monkeypatch):
    from cwproc.sim.sample_data import StreamLineSpec, write_streamline_series

    stream = _Terminal()
    monkeypatch.setattr(progress, "DELAY_S", 0.0)
    monkeypatch.setattr("sys.stderr", stream)
    spec = dataclasses.replace(
        StreamLineSpec(), n_scans=2, scans_per_file=1, n_gates=4, field_shape=(32, 32, 16)
    )
    with progress.reporting(progress.shown_on(quiet=False)):
        write_streamline_series(tmp_path / "d", tmp_path / "t.json", spec)
    assert "scans:" in stream.getvalue() and "/2 [" in stream.getvalue()  # files of 2
    quiet = _Terminal()
    monkeypatch.setattr("sys.stderr", quiet)
    with progress.reporting(progress.shown_on(quiet=True)):
        write_streamline_series(tmp_path / "d", tmp_path / "t.json", spec)
    assert quiet.getvalue() == ""


@pytest.mark.slow
def test_retrieve_of_a_simulated_series_recovers_wind_and_epsilon(tmp_path):
    """``simulate lidar`` then ``retrieve``: the tolerances of the sample's test
    (tests/cli/test_simulate.py): mean wind within 0.5 m/s, median epsilon beyond 240 m
    within 30 % (two blocks of 10 scans, 24 gates)."""
    import json

    import xarray as xr

    sim, out = tmp_path / "sim", tmp_path / "out"
    res = run("simulate", "lidar", "-o", str(sim), "--hours", "0.2", "--seed", "3", "-q")
    assert res.exit_code == 0, res.output
    res = run("retrieve", str(sim / "data"), "-o", str(out), "-q")
    assert res.exit_code == 0, res.output
    truth = json.loads((sim / "truth" / "truth.json").read_text())
    with xr.open_dataset(next(out.glob("*_wind.nc"))) as wind:
        assert float(wind["u"].mean()) == pytest.approx(truth["u_m_s"], abs=0.5)
        assert float(wind["v"].mean()) == pytest.approx(truth["v_m_s"], abs=0.5)
    with xr.open_dataset(next(out.glob("*_turbulence.nc"))) as turb:
        eps = turb["epsilon"].where(turb["range"] >= 240.0).values
    assert 0.7 < np.nanmedian(eps) / truth["epsilon_m2_s3"] < 1.3


def test_a_long_series_is_named_in_one_line(tmp_path):
    """A day of one-scan files would print 1920 ``wrote`` lines: a series of more than four
    files prints its count, first and last, then the truth."""
    from pathlib import Path

    from cwproc.cli.simulate_lidar import written_lines

    res = run(
        "simulate", "lidar", "-o", str(tmp_path), "--hours", "0.0625", "--gates", "4",
        "--scan-period", "45", "--scans-per-file", "1", "-q",
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    files = sorted((tmp_path / "data").glob("*.hpl"))
    assert len(files) == 5
    lines = res.output.strip().splitlines()
    assert lines == [
        f"wrote 5 files {tmp_path / 'data' / files[0].name} .. {files[-1].name}",
        f"wrote {tmp_path / 'truth' / 'truth.json'}",
    ]
    few = [Path("a.hpl"), Path("b.hpl"), Path("truth.json")]
    assert written_lines(few) == ["wrote a.hpl", "wrote b.hpl", "wrote truth.json"]
