"""One scan chain (issue 33): the stage order in ``ScanChain`` only, blocks that do not
depend on the blocks before them, and no allocator tuning in the pipeline."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cwproc.config import load_config
from cwproc.pipeline import group_units, read_input, screened_wind
from cwproc.pipeline.product_units import concat_unit
from cwproc.sim.sample_data import StreamLineSpec, write_streamline_series
from cwproc.stages.structure import azimuth_structure_function

PIPELINE = Path(__file__).resolve().parents[1] / "cwproc" / "pipeline"
#: the stages of the scan chain, whose order only ScanChain (scan_chain.py) may know
SCAN_STAGES = {"qc", "vad", "structure", "epsilon", "stare", "doppler_lidar"}


def stage_imports(source: str) -> set[str]:
    """The ``cwproc.stages`` modules ``source`` imports (at any depth, any form)."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names = [f"{node.module}.{a.name}" for a in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[:2] == ["cwproc", "stages"] and len(parts) > 2:
                found.add(parts[2])
    return found


@pytest.mark.parametrize(
    ("source", "stages"),
    [
        ("from cwproc.stages import qc, vad\n", {"qc", "vad"}),
        ("def f():\n    from cwproc.stages.structure import azimuth_step\n", {"structure"}),
        ("import cwproc.stages.epsilon as e\n", {"epsilon"}),
        ("import numpy\nfrom cwproc.pipeline.scan_chain import ScanChain\n", set()),
    ],
)
def test_stage_imports_are_found(source, stages):
    assert stage_imports(source) == stages


def test_only_the_scan_chain_knows_the_stage_order():
    """The executor (stream.py) and the entry (run.py) import no stage; the scan
    chain's stages are imported by scan_chain.py alone (background_files.py wraps the SNR
    correction stage that ScanChain.prepare calls)."""
    by_module = {
        p.name: stage_imports(p.read_text(encoding="utf-8")) for p in PIPELINE.glob("*.py")
    }
    assert by_module["stream.py"] == set() and by_module["run.py"] == set()
    assert SCAN_STAGES <= by_module["scan_chain.py"]
    others = {n: found & SCAN_STAGES for n, found in by_module.items() if n != "scan_chain.py"}
    assert not any(others.values()), others
    assert {n for n, found in by_module.items() if "snr_correction" in found} == {
        "background_files.py"
    }


def test_no_allocator_tuning_in_library_code():
    """Only cwproc.memory (switched on by the program and batch workers) uses ctypes;
    nothing in the pipeline calls mallopt or malloc_trim."""
    package = PIPELINE.parent
    for path in package.rglob("*.py"):
        if path.name == "memory.py" and path.parent == package:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import | ast.ImportFrom):
                names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
                assert "ctypes" not in names, f"{path}:{node.lineno} imports ctypes"
            if isinstance(node, ast.Attribute):
                assert node.attr not in ("mallopt", "malloc_trim"), f"{path}:{node.lineno}"


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    """Screened scans and wind rows of 25 simulated VAD scans (blocks of 10)."""
    folder = tmp_path_factory.mktemp("chain")
    spec = StreamLineSpec(n_scans=25, scans_per_file=1, n_gates=24, seed=43)
    write_streamline_series(folder / "day", folder / "truth.json", spec)
    config = load_config("streamline")
    (unit,) = group_units(read_input(p, config) for p in sorted((folder / "day").glob("*.hpl")))
    return screened_wind(concat_unit(unit), config)


def test_blocks_of_a_whole_day_are_its_block_aligned_slices(day):
    """The shift-invariance that replaced ``time_origins``: blocks computed a few at a
    time (as a streamed day reduces them) equal the whole day's, time centres and scan
    periods included, bit for bit."""
    screened, wind = day
    whole = azimuth_structure_function(screened, wind, n_scans=10)
    assert whole.sizes["time"] == 3
    pieces = []
    for start, stop in ((0, 10), (10, 20), (20, 25)):
        part = wind.isel(time=slice(start, stop))
        rays = np.isin(screened["scan"].values, part["scan"].values)
        pieces.append(
            azimuth_structure_function(screened.isel(ray=np.flatnonzero(rays)), part, n_scans=10)
        )
    joined = xr.concat(pieces, dim="time", data_vars="minimal", coords="minimal",
                       compat="override", join="override", combine_attrs="override")  # fmt: skip
    xr.testing.assert_identical(joined, whole)


def test_block_times_follow_a_shift_of_the_day_exactly(day):
    """Shifted by a day and an odd number of nanoseconds, every block centre moves by
    exactly the shift and every other value stays the same (integer-ns arithmetic)."""
    screened, wind = day
    shift = np.timedelta64(86_400_000_000_000 + 123_456_789, "ns")
    moved = azimuth_structure_function(
        screened.assign_coords(time=screened["time"] + shift),
        wind.assign_coords(time=wind["time"] + shift),
        n_scans=10,
    )
    whole = azimuth_structure_function(screened, wind, n_scans=10)
    np.testing.assert_array_equal(moved["time"].values, whole["time"].values + shift)
    xr.testing.assert_identical(moved.assign_coords(time=whole["time"]), whole)


def test_block_centre_is_the_mean_time_rounded_half_up(day):
    """The centre of a block is its mean wind time, rounded half up to the ns."""
    screened, wind = day
    sf = azimuth_structure_function(screened, wind, n_scans=10)
    t = wind["time"].values.astype("datetime64[ns]").astype(np.int64)
    for k, centre in enumerate(sf["time"].values.astype(np.int64)):
        block = t[10 * k : 10 * k + 10]
        offset = block - block[0]
        expected = block[0] + (2 * int(offset.sum()) + block.size) // (2 * block.size)
        assert centre == expected
        assert abs(centre - block.mean()) <= 0.5


def test_day_decisions_are_those_the_stages_make(day):
    """ScanChain.decisions from the pointing alone: the scans the VAD fitted, its
    elevation, and the structure function's azimuth step and rotation; a record that
    differs in any of them is named."""
    import dataclasses

    from cwproc.pipeline.scan_chain import Pointing, ScanChain

    screened, wind = day
    chain = ScanChain(load_config("streamline"))
    pointing = Pointing(
        screened["time"].values,
        screened["azimuth"].values.astype(float),
        screened["elevation"].values.astype(float),
        str(screened.attrs.get("scan_type", "")),
    )
    decided = chain.decisions(pointing, wind=True, step=True)
    sf = azimuth_structure_function(screened, wind, n_scans=10)
    np.testing.assert_array_equal(decided.scan, screened["scan"].values)
    np.testing.assert_array_equal(decided.wind_scans, wind["scan"].values)
    assert decided.vad_elevation_deg == wind.attrs["vad_elevation_deg"]
    assert decided.azimuth_step == (float(sf["azimuth_step"][0]), float(sf.attrs["rotation"]))
    assert decided.differences(decided) == ""
    changes = {
        "scan numbering": {"scan": decided.scan[::-1]},
        "conical elevation": {"vad_elevation_deg": 60.0},
        "conical scans of the day": {"wind_scans": decided.wind_scans[1:]},
        "azimuth step": {"azimuth_step": (decided.azimuth_step[0] * 2, 1.0)},
    }
    for reason, change in changes.items():
        assert decided.differences(dataclasses.replace(decided, **change)) == reason
    assert chain.decisions(pointing, wind=False, step=False).vad_elevation_deg is None


def test_a_whole_run_takes_one_dataset():
    """whole=True means the one dataset is the day (its last block is reduced short)."""
    from cwproc.pipeline.scan_chain import ScanChain
    from cwproc.pipeline.stream import run_scan_chain

    chain = ScanChain(load_config("streamline"))
    with pytest.raises(ValueError, match="one dataset"):
        run_scan_chain(chain, [None, None], whole=True)
    assert run_scan_chain(chain, [None], whole=False) is None  # no chunk: run it whole
