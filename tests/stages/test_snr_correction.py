"""Stage ``background``: rays matched to the background of their hour, dataset built."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cwproc.pipeline.background_files import find_background_files
from cwproc.stages.snr_correction import correct_snr, match_rays


def _t(text: str) -> np.datetime64:
    return np.datetime64(text, "ns")


def test_rays_take_the_latest_background_before_them():
    bg = np.array([_t("2024-06-01T10:00:05"), _t("2024-06-01T11:00:04")])
    rays = np.array(
        [
            _t("2024-06-01T09:59:00"),  # before every background
            _t("2024-06-01T10:00:05"),  # at the background time
            _t("2024-06-01T10:59:59"),
            _t("2024-06-01T11:30:00"),
            _t("2024-06-01T14:00:00"),  # 3 h after the last one
        ]
    )
    np.testing.assert_array_equal(match_rays(rays, bg, 2.0), [-1, 0, 0, 1, -1])
    np.testing.assert_array_equal(match_rays(rays, bg, None), [-1, 0, 0, 1, 1])


def _scans(n_rays: int = 4, n_gates: int = 120) -> xr.Dataset:
    rng = (np.arange(n_gates) + 0.5) * 30.0
    t = _t("2024-06-01T10:10:00") + np.arange(n_rays) * np.timedelta64(20, "m")
    noise = np.random.default_rng(2).normal(0, 1e-3, (n_rays, n_gates))
    return xr.Dataset(
        {"snr": (("ray", "range"), 0.002 + noise)},
        coords={"time": ("ray", t), "range": rng},
        attrs={"instrument_kind": "streamline"},
    )


def _background(when: str, n_gates: int, name: str) -> xr.Dataset:
    values = 1.7e7 * (1.0 + 1e-5 * (np.arange(n_gates) + 0.5) * 30.0)
    return xr.Dataset(
        {"background": ("range", values)},
        coords={"time": _t(when), "gate": ("range", np.arange(n_gates))},
        attrs={"source_files": [name]},
    )


def test_uncorrected_snr_kept_and_rays_without_background_unchanged():
    scans = _scans()  # rays at 10:10, 10:30, 10:50, 11:10
    bg = _background("2024-06-01T10:00:02", 150, "Background_010624-100002.txt")
    notes: list[str] = []
    out = correct_snr(scans, [bg], max_age_h=1.0, notes=notes)
    np.testing.assert_array_equal(out["snr_uncorrected"].values, scans["snr"].values)
    done = ~np.isnat(out["background_time"].values)
    np.testing.assert_array_equal(done, [True, True, True, False])  # 11:10 is > 1 h after
    np.testing.assert_array_equal(out["snr"].values[3], scans["snr"].values[3])
    # corrected rays: the +0.002 floor offset is divided out (noise sd 1e-3, ~110 gates)
    assert np.all(np.abs(np.nanmean(out["snr"].values[:3, 3:], axis=1)) < 5e-4)
    np.testing.assert_allclose(out["noise_floor"].values[:3], 1.002, atol=5e-4)
    assert "Manninen et al. (2016)" in out.attrs["snr_correction"]
    assert out.attrs["background_files"] == ["Background_010624-100002.txt"]
    assert notes == [
        "SNR of 3 of 4 rays corrected with 1 background file(s) "
        "(Manninen et al. (2016), Vakkari et al. (2019))"
    ]


def test_background_with_too_few_gates_is_noted_not_used():
    notes: list[str] = []
    bg = _background("2024-06-01T10:00:02", 100, "Background_010624-100002.txt")
    out = correct_snr(_scans(), [bg], notes=notes)
    assert "100 gates, the scans have 120" in notes[0]
    assert "none of 4 rays" in notes[1]
    assert out.attrs["snr_correction"] == "none"
    np.testing.assert_array_equal(out["snr"].values, out["snr_uncorrected"].values)


def test_background_files_found_beside_the_data_or_in_a_folder(tmp_path):
    data = tmp_path / "d"
    other = tmp_path / "bg"
    data.mkdir()
    other.mkdir()
    for folder, name in [(data, "Background_010624-100002.txt"), (other, "x-Background_0.txt")]:
        (folder / name).write_text("1.000000\r\n")
    (data / "VAD_1_20240601_100000.hpl").write_text("")
    found = find_background_files([data / "VAD_1_20240601_100000.hpl"])
    assert [p.name for p in found] == ["Background_010624-100002.txt"]
    assert [p.name for p in find_background_files([], other)] == ["x-Background_0.txt"]


@pytest.mark.realdata
def test_real_stares_corrected_like_doppy_figures(real_data):
    """docs/streamline-background.md: Eriswil noise floor and gate counts of the benchmark."""
    from cwproc.io import read_file
    from cwproc.pipeline.background_files import read_backgrounds

    hpl = real_data / "hpl"
    ds = read_file(hpl / "eriswil-2022-12-14-Stare_91_20221214_11.hpl")
    bgs = read_backgrounds([hpl / "background" / "eriswil-Background_141222-000013.txt"])
    out = correct_snr(ds, bgs, max_age_h=None)
    np.testing.assert_allclose(out["noise_floor"].values, [1.000459, 1.000837], atol=2e-6)
    assert int((out["snr_uncorrected"] >= 0.008).sum()) == 40
    assert int((out["snr"] >= 0.008).sum()) == 39
    # gates within 90 m are outside the fits and keep the instrument's SNR
    near = out["range"].values <= 90.0
    np.testing.assert_array_equal(
        out["snr"].values[:, near], out["snr_uncorrected"].values[:, near]
    )


def test_only_the_backgrounds_the_rays_need_are_read(tmp_path):
    from cwproc.pipeline.background_files import read_backgrounds

    good = "".join(f"{1.7e7 + i:.6f}\r\n" for i in range(130)).encode()
    for name in ("Background_010624-100002.txt", "Background_010624-110003.txt"):
        (tmp_path / name).write_bytes(good)
    (tmp_path / "Background_010624-090001.txt").write_bytes(b"damaged\r\n")  # not needed
    (tmp_path / "Background_010624-120001.txt").write_bytes(b"damaged\r\n")  # after the rays
    rays = _t("2024-06-01T11:10:00") + np.arange(3) * np.timedelta64(15, "m")
    notes: list[str] = []
    found = read_backgrounds(sorted(tmp_path.iterdir()), notes, ray_time=rays, max_age_h=2.0)
    assert [b.attrs["source_files"][0] for b in found] == ["Background_010624-110003.txt"]
    assert notes == []
    rays = np.r_[_t("2024-06-01T09:30:00"), rays]  # now the 09:00 one is needed
    found = read_backgrounds(sorted(tmp_path.iterdir()), notes, ray_time=rays, max_age_h=2.0)
    assert len(found) == 1 and "Background_010624-090001.txt:1: byte 1: joined" in notes[0]
