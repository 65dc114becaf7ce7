"""The shipped sample data: deterministic regeneration, format and truth."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cwproc.sim.sample_data import SAMPLE_SPEC, write_sample_data

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data"


def test_sample_folder_holds_only_hpl_files_under_4_mb():
    files = sorted((SAMPLE / "streamline").iterdir())
    assert files, "sample_data/streamline is empty"
    assert all(f.suffix == ".hpl" for f in files)
    assert sum(f.stat().st_size for f in files) <= 4 * 1024 * 1024


@pytest.mark.slow
def test_regeneration_is_byte_identical(tmp_path):
    written = write_sample_data(tmp_path)
    shipped_names = sorted(str(f.relative_to(SAMPLE)) for f in SAMPLE.rglob("*") if f.is_file())
    names = sorted(str(f.relative_to(tmp_path)) for f in written)
    # besides the generated files only the README and the two configurations ship
    assert sorted(set(shipped_names) - set(names)) == ["README.md", "site.toml", "sonic.toml"]
    for name in names:
        assert (tmp_path / name).read_bytes() == (SAMPLE / name).read_bytes(), name


def test_samples_total_under_4_mb():
    total = sum(f.stat().st_size for f in SAMPLE.rglob("*") if f.is_file())
    assert total <= 4 * 1024 * 1024


@pytest.mark.parametrize(
    ("folder", "fmt", "config"),
    [
        ("zephir", "zephir_csv", "zephir300"),
        ("windcube", "windcube_sta", "windcube"),
        ("sonic", "toa5", "sonic.toml"),
        ("sonic", "tob1", "sonic.toml"),
        ("sonic", "ghg", "sonic.toml"),
        ("sonic", "gill", "sonic.toml"),
        ("sonic", "meteo2", "sonic.toml"),
    ],
)
def test_every_format_has_a_sample_its_reader_reads(folder, fmt, config):
    """Every reader is covered by a shipped sample (no ../shared needed)."""
    from cwproc.config import load_config
    from cwproc.io import Format, detect_format
    from cwproc.pipeline import read_input

    cfg = load_config(SAMPLE / config if config.endswith(".toml") else config)
    files = [f for f in sorted((SAMPLE / folder).iterdir()) if detect_format(f) is Format(fmt)]
    # the sonic record once per format; ZephIR 10-min and 1-s; WindCube v1, v2, v2.1 and
    # v2.1 one-minute statistics
    assert len(files) == {"zephir": 2, "windcube": 4}.get(folder, 1)
    for path in files:
        ds = read_input(path, cfg).dataset
        assert ds.sizes["time"] >= 36
        if folder == "sonic":
            spec = json.loads((SAMPLE / "sonic_truth.json").read_text())["spec"]
            speed = np.hypot(ds["u"].values.mean(), ds["v"].values.mean())
            assert speed == pytest.approx(spec["speed"], rel=0.25)
        else:
            truth = json.loads((SAMPLE / "wind_records_truth.json").read_text())
            mean = ds["wind_speed"].mean("time")
            profile = mean.sel(height=truth["heights_m"], method="nearest")
            np.testing.assert_allclose(profile.values, truth["wind_speed_m_s"], rtol=0.05)


def test_sample_files_read_back_with_enough_scans_and_the_true_mean_wind():
    from cwproc.io.halo import read_hpl

    truth = json.loads((SAMPLE / "streamline_truth.json").read_text())
    datasets = [read_hpl(p) for p in sorted((SAMPLE / "streamline").glob("*.hpl"))]
    n_scans = sum(int(ds["scan"].max()) + 1 for ds in datasets)
    assert n_scans >= 10  # the turbulence block (N = 10 scans) runs
    assert n_scans == SAMPLE_SPEC.n_scans
    # the radial velocities average to the projection of the true wind: least squares of
    # V_r = cos(phi) (u sin(theta) + v cos(theta)) + w sin(phi) over all rays and gates
    az = np.deg2rad(np.concatenate([ds["azimuth"].values for ds in datasets]))
    el = np.deg2rad(np.concatenate([ds["elevation"].values for ds in datasets]))
    vr = np.concatenate([ds["radial_velocity"].values for ds in datasets]).mean(axis=1)
    design = np.column_stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    (u, v, w), *_ = np.linalg.lstsq(design, vr, rcond=None)
    # turbulence sigma_V ~ 1.2 m/s averaged over 24 gates and 12 scans of a field with
    # L_V = 150 m: the mean over the box is uncertain by a few tenths of a m/s
    assert u == pytest.approx(truth["u_m_s"], abs=0.6)
    assert v == pytest.approx(truth["v_m_s"], abs=0.6)
    assert w == pytest.approx(0.0, abs=0.6)
