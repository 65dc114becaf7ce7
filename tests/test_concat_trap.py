"""The ``xr.concat`` trap of issue 33: refused with a clear message, or joined right.

Every file numbers its scans from 0, so ``xr.concat`` of two ``.hpl`` datasets merges
scan k of each file: the VAD fit gave 6 wind rows instead of 12 on the two sample
files, without a warning. The scan stages now refuse such a dataset
(:mod:`cwproc.stages.scan_guard`), naming ``cwproc.read``; ``cwproc.read`` of several
files and ``cwproc.concat_scans`` number the scans over the record. The guard never
trips on data numbered by cwproc (sample and simulated days).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import cwproc
from cwproc.errors import CwprocError, InputFileError
from cwproc.sim.sample_data import StreamLineSpec, streamline_files
from cwproc.stages import azimuth_structure_function, fit_vad, screen_radial_velocity
from cwproc.stages.scan_guard import require_distinct_scans

STREAMLINE = Path(__file__).resolve().parents[1] / "sample_data" / "streamline"
FILES = sorted(STREAMLINE.glob("*.hpl"))
HOW = r"join the files with cwproc\.read\(\[\.\.\.\]\) or cwproc\.concat_scans\(\[\.\.\.\]\)"

#: a small simulated day: one scan per file (the Stream Line's usual layout)
SPEC = StreamLineSpec(
    n_scans=4,
    scans_per_file=1,
    rays_per_scan=36,
    scan_period_s=18.0,
    n_gates=4,
    field_shape=(48, 48, 24),
)


@pytest.fixture(scope="module")
def per_file() -> list[xr.Dataset]:
    return [cwproc.read(f) for f in FILES]


@pytest.fixture(scope="module")
def simulated_files() -> list[xr.Dataset]:
    return list(streamline_files(SPEC))


def test_xr_concat_of_the_sample_files_is_refused_by_every_scan_stage(per_file):
    glued = xr.concat(per_file, dim="ray")
    message = (
        r"scan 0 holds rays of 12:00:00-12:00:35 and 12:03:36-12:04:11: datasets joined "
        r"with xarray\.concat keep each file's scan numbers \(every file numbers from 0\); "
    )
    with pytest.raises(CwprocError, match="^fit_vad: " + message + HOW + "$"):
        fit_vad(glued)
    with pytest.raises(CwprocError, match="^screen_radial_velocity: " + message):
        screen_radial_velocity(glued)
    right = cwproc.read(FILES)
    screened = screen_radial_velocity(right)
    wind = fit_vad(screened)
    with pytest.raises(CwprocError, match="^azimuth_structure_function: " + message):
        azimuth_structure_function(xr.concat(per_file, dim="ray"), wind)


def test_the_right_join_gives_twelve_wind_rows(per_file, monkeypatch):
    joined = cwproc.read(FILES)
    assert int(joined["scan"].max()) == 11
    wind = fit_vad(joined)
    assert wind.sizes["time"] == 12
    assert np.all(np.diff(wind["time"].values) > np.timedelta64(0, "s"))
    xr.testing.assert_identical(cwproc.concat_scans(per_file), joined)
    xr.testing.assert_identical(cwproc.read(str(STREAMLINE / "*.hpl")), joined)
    xr.testing.assert_equal(cwproc.read(FILES[::-1]), joined)  # attrs: the first file's
    # what the trap gave without the guard: scan k of both files fitted as one rotation
    monkeypatch.setattr("cwproc.stages.vad.require_distinct_scans", lambda ds, stage: None)
    assert fit_vad(xr.concat(per_file, dim="ray")).sizes["time"] == 6


def test_one_scan_per_file_glued_back_to_back_is_refused(simulated_files):
    """Every ray is scan 0 and the scan numbers never decrease: the turned azimuth of
    the one 'scan' (two rotations) gives it away."""
    glued = xr.concat(simulated_files[:2], dim="ray")
    assert set(np.unique(glued["scan"].values)) == {0}
    with pytest.raises(CwprocError, match=r"more than one full turn of the azimuth\): datas"):
        fit_vad(glued)
    joined = cwproc.concat_scans(simulated_files)
    assert fit_vad(joined).sizes["time"] == SPEC.n_scans


def test_one_scan_per_file_far_apart_is_refused(per_file):
    """Scan 0 of each sample file only: one scan per file, 3.5 min apart."""
    firsts = [ds.isel(ray=np.flatnonzero(ds["scan"].values == 0)) for ds in per_file]
    with pytest.raises(CwprocError, match=r"\(more than 120 s apart\): datasets joined"):
        fit_vad(xr.concat(firsts, dim="ray"))
    assert fit_vad(cwproc.concat_scans(firsts)).sizes["time"] == 2


def test_the_guard_passes_every_numbering_of_cwproc(per_file, simulated_files):
    """Sample files alone and joined, in any order; simulated days file by file, joined,
    reversed and with stares between scans (scan -1); subsets of scans."""
    for ds in [*per_file, cwproc.read(FILES), cwproc.read(FILES[::-1])]:
        require_distinct_scans(ds, stage="test")
    joined = cwproc.concat_scans(simulated_files)
    require_distinct_scans(joined, stage="test")
    require_distinct_scans(cwproc.concat_scans(simulated_files[::-1]), stage="test")
    backwards = joined.isel(ray=slice(None, None, -1))  # rays in reverse time order
    require_distinct_scans(backwards, stage="test")
    stare = joined["scan"].values == 1
    with_stares = joined.assign_coords(
        elevation=joined["elevation"].where(~stare, 90.0),
        scan=joined["scan"].where(~stare, -1),
    )
    require_distinct_scans(with_stares, stage="test")
    every_other = joined.isel(ray=np.flatnonzero(joined["scan"].values % 2 == 0))
    require_distinct_scans(every_other, stage="test")
    assert fit_vad(every_other).sizes["time"] == SPEC.n_scans // 2


def test_read_of_many_files_names_what_it_cannot_join(tmp_path):
    sonic = Path(__file__).resolve().parents[1] / "sample_data" / "sonic"
    with pytest.raises(InputFileError, match=r"TOA5_999.*a sonic file \(toa5\), but .*scan"):
        cwproc.read([FILES[0], sonic / "TOA5_999.ts_data_2024_06_01_1200.dat"])
    with pytest.raises(InputFileError, match="no file matches this pattern"):
        cwproc.read(str(tmp_path / "*.hpl"))
    with pytest.raises(TypeError, match="takes a path, a glob pattern or a sequence"):
        cwproc.read(xr.Dataset())
    with pytest.raises(CwprocError, match="no file given"):
        cwproc.read([])
