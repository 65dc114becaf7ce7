"""End to end: `cwproc retrieve` on .hpl files, good, bad and mixed."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.halo import write_hpl
from cwproc.io.netcdf import read_product

U_TRUE, V_TRUE, W_TRUE = 6.0, -3.0, 0.2


def synthetic_vad(
    n_scans: int = 12,
    n_rays: int = 24,
    n_gates: int = 40,
    seed: int = 3,
    elevation: float = 60.0,
    noise: float = 0.15,
) -> xr.Dataset:
    """Stream Line step-stare VAD scans of a uniform wind plus Gaussian noise."""
    rng = np.random.default_rng(seed)
    az = np.tile(np.arange(n_rays) * 360.0 / n_rays, n_scans)
    el = np.full(az.size, elevation)
    t0 = np.datetime64("2024-05-01T10:00:00", "ns")
    t = t0 + (np.arange(az.size) * 1.5e9).astype("timedelta64[ns]")
    rng_m = (np.arange(n_gates) + 0.5) * 30.0
    phi, th = np.radians(el)[:, None], np.radians(az)[:, None]
    vr = W_TRUE * np.sin(phi) + np.cos(phi) * (U_TRUE * np.sin(th) + V_TRUE * np.cos(th))
    vr = np.broadcast_to(vr, (az.size, n_gates)) + rng.normal(0, noise, (az.size, n_gates))
    snr = np.full((az.size, n_gates), 0.5)
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), vr),
            "snr": (("ray", "range"), snr),
            "beta": (("ray", "range"), np.full((az.size, n_gates), 1e-6)),
        },
        coords={
            "time": ("ray", t),
            "azimuth": ("ray", az),
            "elevation": ("ray", el),
            "range": rng_m,
        },
        attrs={
            "system_id": "77",
            "gate_length_m": 30.0,
            "scan_type": "VAD",
            "instrument": "Halo Photonics Stream Line",
        },
    )


@pytest.fixture()
def vad_files(tmp_path):
    ds = synthetic_vad()
    half = ds.sizes["ray"] // 2
    folder = tmp_path / "in"
    folder.mkdir()
    write_hpl(ds.isel(ray=slice(0, half)), folder / "VAD_77_20240501_100000.hpl")
    write_hpl(ds.isel(ray=slice(half, None)), folder / "VAD_77_20240501_100300.hpl")
    return folder


def run(args):
    return CliRunner().invoke(main, ["retrieve", *map(str, args)])


def test_known_wind_recovered_from_two_files(vad_files, tmp_path):
    out = tmp_path / "out"
    res = run([vad_files, "-o", out])
    assert res.exit_code == 0, res.output
    winds = sorted(out.glob("*_wind.nc"))
    assert len(winds) == 1  # both files are one instrument-day unit
    wind = read_product(winds[0])
    assert wind.sizes["time"] == 12
    good = wind.where(wind["qc_flag"] == 0)
    # 24 rays, sigma 0.15 m/s at 60 deg elevation: predicted std of u ~ 0.15*sqrt(2/24)/0.5
    assert float(np.abs(good["u"] - U_TRUE).max()) < 5 * 0.15 * np.sqrt(2 / 24) / 0.5
    assert float(np.abs(good["v"] - V_TRUE).max()) < 5 * 0.15 * np.sqrt(2 / 24) / 0.5
    assert float(np.abs(good["w"] - W_TRUE).max()) < 5 * 0.15 / np.sqrt(24) / np.sin(np.radians(60))
    direction = np.degrees(np.arctan2(-U_TRUE, -V_TRUE)) % 360
    assert float(np.abs(good["wind_direction"] - direction).max()) < 3.0
    assert (
        "input_sha256" in wind.attrs and "VAD_77_20240501_100000.hpl" in wind.attrs["input_files"]
    )
    assert list(out.glob("*.tmp")) == [] and list(out.glob(".*")) == []


def test_bad_file_among_good_ones(vad_files, tmp_path):
    bad = vad_files / "VAD_77_20240501_100600.hpl"
    text = (vad_files / "VAD_77_20240501_100000.hpl").read_text().splitlines(keepends=True)
    text[30] = "  12 abc 1.5 1e-6\r\n"  # non-numeric Doppler on line 31
    bad.write_text("".join(text))
    out = tmp_path / "out"
    res = run([vad_files, "-o", out])
    assert res.exit_code == 1
    failures = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(failures) == 1
    assert "VAD_77_20240501_100600.hpl:31:" in failures[0]
    assert len(list(out.glob("*_wind.nc"))) == 1  # the good files still processed


def test_real_files_each_fail_or_succeed_with_one_line(real_data, tmp_path):
    out = tmp_path / "out"
    res = run([real_data / "hpl", "-o", out])
    assert res.exit_code == 1
    errors = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    corrupt = [e for e in errors if "CORRUPT_warsaw" in e]
    assert len(corrupt) == 1 and ".hpl:3019:" in corrupt[0]
    # the three stares give stare products (w statistics; eps needs a VAD that day)
    assert not [e for e in errors if "Stare" in e and "CORRUPT" not in e]
    assert len(list(out.glob("*_stare.nc"))) == 3
    assert res.output.count("stare eps not computed: no VAD") == 3
    # the 6-ray VAD gives no valid wind (too few rays, 60 deg gaps): no product, a note
    assert list(out.glob("*_wind.nc")) == []
    assert "no wind product written: every u is missing (qc_flag: too_few_rays" in res.output
    for p in out.iterdir():
        assert p.suffix == ".nc"
        read_product(p)  # every product opens


def test_unknown_file_named_explicitly_fails(tmp_path):
    f = tmp_path / "notes.txt"
    f.write_text("hello\n")
    res = run([f, "-o", tmp_path / "o"])
    assert res.exit_code == 1
    assert "notes.txt:1: not a format cwproc reads" in res.output


def test_time_order_is_restored_across_files(vad_files, tmp_path):
    files = sorted(vad_files.glob("*.hpl"))
    out = tmp_path / "out"
    res = run([files[1], files[0], "-o", out])
    assert res.exit_code == 0, res.output
    wind = read_product(next(out.glob("*_wind.nc")))
    t = pd.to_datetime(wind["time"].values)
    assert t.is_monotonic_increasing


def test_sample_data_products_are_cf_and_acdd_compliant(tmp_path, compliance):
    """The README's main job: CF-1.10 without high-priority failures, ACDD-1.3 >= 88 %."""
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    out = tmp_path / "out"
    res = run([repo / "sample_data", "-c", repo / "sample_data" / "site.toml", "-o", out])
    assert res.exit_code == 0, res.output
    products = sorted(out.glob("*.nc"))
    assert [p.name.rsplit("_", 1)[1] for p in products] == ["turbulence.nc", "wind.nc"]
    for product in products:
        high, acdd = compliance(product)
        assert high == [], product.name
        # the turbulence product carries the dissipation rate, EDR, L_V, sigma_V^2 and
        # their standard errors, for which CF has no standard name (ACDD 0.89 there)
        assert acdd >= 0.88, (product.name, acdd)


@pytest.mark.slow
def test_cw_scans_with_a_pulsed_config_get_wind_but_no_wrong_epsilon(tmp_path):
    """The default (pulsed Stream Line) config on a cw series: the probe would be wrong.

    A pulsed range gate instead of the focused cw Lorentzian made eps 3-25 times too low
    at 200-500 m; the turbulence product is left out with a note naming the cause, and
    the wind product (independent of the probe) is written.
    """
    from cwproc.sim.cw import CWLidar, write_cw_series

    write_cw_series(
        tmp_path / "data",
        tmp_path / "truth.json",
        np.random.default_rng(1),
        CWLidar(),
        heights_m=np.array([100.0]),
        wind_speed=np.array([8.0]),
        wind_direction_deg=240.0,
        sigma2=np.array([1.0]),
        outer_scale_m=np.array([200.0]),
        n_scans=10,
        start=np.datetime64("2024-01-01T00:00:00"),
    )
    res = CliRunner().invoke(main, ["retrieve", str(tmp_path / "data"), "-o", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    assert "turbulence not computed" in res.output and "cw lidar" in res.output
    assert "-c banakh1999" in res.output
    assert [p.name.endswith("_wind.nc") for p in (tmp_path / "o").iterdir()] == [True]
    res = CliRunner().invoke(
        main, ["retrieve", str(tmp_path / "data"), "-c", "banakh1999", "-o", str(tmp_path / "c")]
    )
    assert res.exit_code == 0, res.output
    assert sorted(p.name.split("_")[-1] for p in (tmp_path / "c").iterdir()) == [
        "turbulence.nc",
        "wind.nc",
    ]


def test_stream_line_scans_with_a_cw_config_are_refused(vad_files, tmp_path):
    """Stream Line files (instrument_kind "streamline") are pulsed: a cw configuration is
    a failure for each file, naming it, both instruments and the preset to use."""
    cfg = tmp_path / "cw.toml"
    cfg.write_text('[instrument]\nkind = "cw"\nz_r_coefficient = 0.0013\n')
    res = CliRunner().invoke(
        main, ["retrieve", str(vad_files), "-c", str(cfg), "-o", str(tmp_path / "o")]
    )
    assert res.exit_code == 1, res.output
    errors = [x for x in res.output.splitlines() if x.startswith("error:")]
    assert len(errors) == 2
    assert all("pulsed lidar" in e and "cw lidar" in e and "-c streamline" in e for e in errors)
    assert not list((tmp_path / "o").glob("*.nc"))


@pytest.mark.parametrize(
    ("system_id", "expected"),
    [
        ("../../../../tmp/pwned", "tmp-pwned"),
        ("a\x00b", "a-b"),
        ("x" * 300, "x" * 40),
        ("..", "x"),
    ],
)
def test_system_id_cannot_place_products_outside_the_output(tmp_path, system_id, expected):
    """A hostile `System ID:` header gives a plain product name inside -o (issue 17.1)."""
    path = tmp_path / "in" / "VAD_1.hpl"
    path.parent.mkdir()
    write_hpl(synthetic_vad(n_scans=2).assign_attrs(system_id="77"), path)
    text = path.read_bytes().replace(b"System ID:\t77", b"System ID:\t" + system_id.encode())
    path.write_bytes(text)
    out = tmp_path / "deep" / "out"
    res = run([path, "-o", out, "-c", "streamline"])
    assert res.exit_code == 0, res.output
    outside = [p for p in tmp_path.rglob("*.nc") if p.parent != out]
    assert outside == []
    assert (out / f"streamline_{expected}_20240501_wind.nc").exists()


def test_inputs_read_again_beyond_the_memory_budget_give_the_same_products(tmp_path, monkeypatch):
    """retrieve keeps at most RETRIEVE_MEMORY_BYTES of inputs; beyond, it reads a unit's
    files again when it processes the unit: same products (issue 17.8)."""
    from cwproc import pipeline
    from cwproc.config import load_config

    folder = tmp_path / "in"
    folder.mkdir()
    for day in (1, 2, 3):
        ds = synthetic_vad(n_scans=4, seed=day)
        ds = ds.assign_coords(time=ds["time"] + np.timedelta64(day, "D"))
        write_hpl(ds, folder / f"VAD_77_2024050{day + 1}_100000.hpl")
    config = load_config("streamline")
    files = sorted(folder.glob("*.hpl"))
    kept = pipeline.retrieve_files(files, tmp_path / "kept", config, keep_products=True)
    monkeypatch.setattr("cwproc.pipeline.retrieve.RETRIEVE_MEMORY_BYTES", 0)
    reread = pipeline.retrieve_files(files, tmp_path / "reread", config, keep_products=True)
    assert kept.ok and reread.ok and len(kept.products) == len(reread.products) >= 3
    for (k1, n1, a), (k2, n2, b) in zip(kept.products, reread.products, strict=True):
        assert (k1, n1) == (k2, n2)
        xr.testing.assert_identical(a, b)


def test_files_in_a_row_that_held_the_same_get_one_note(tmp_path):
    """Six files of one scan each: one note names the first and last and how many; a
    file that held something else keeps its own note, and so do the other notes."""
    ds = synthetic_vad(n_scans=12)
    folder = tmp_path / "in"
    folder.mkdir()
    per_file = 2 * 24
    for k in range(6):
        part = ds.isel(ray=slice(k * per_file, (k + 1) * per_file))
        write_hpl(part, folder / f"VAD_77_20240501_10{k:02d}00.hpl")
    res = run([folder, "-o", tmp_path / "out", "-c", "streamline"])
    assert res.exit_code == 0, res.output
    notes = [line for line in res.output.splitlines() if line.startswith("note: ")]
    alike = [line for line in notes if "conical scan(s)" in line]
    assert len(alike) == 1, notes
    first, last = folder / "VAD_77_20240501_100000.hpl", folder / "VAD_77_20240501_100500.hpl"
    assert (
        alike[0]
        == f"note: 6 files {first} .. {last}: VAD: 2 conical scan(s) -> wind (and turbulence)"
    )


def test_collapsed_notes_keep_other_lines_and_short_runs_in_place():
    from cwproc.cli._common import ALIKE_FILES_MIN, collapsed_notes

    paths = [f"d/f{k}.hpl" for k in range(9)]
    same = "VAD: 1 conical scan(s) -> wind (and turbulence)"
    notes = [f"{p}: {same}" for p in paths[:5]]
    notes += [f"{paths[5]}: VAD: 40 vertical stare rays -> stare product"]
    notes += [f"{p}: {same}" for p in paths[6:9]]  # a run shorter than ALIKE_FILES_MIN
    notes += ["SNR of 9 files corrected", "d/unknown.hpl: VAD: not an input, kept"]
    got = collapsed_notes(notes, paths)
    assert ALIKE_FILES_MIN == 4
    assert got == [
        f"5 files d/f0.hpl .. d/f4.hpl: {same}",
        notes[5],
        *notes[6:9],
        "SNR of 9 files corrected",
        "d/unknown.hpl: VAD: not an input, kept",
    ]
    assert collapsed_notes([], paths) == []
    assert collapsed_notes(notes[:3], paths) == notes[:3]
