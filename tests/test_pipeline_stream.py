"""A day of scans processed chunk by chunk gives the products of the whole day (issue 15.3)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cwproc.config import load_config
from cwproc.pipeline import group_units, process_scan_day, read_input
from cwproc.pipeline.background_files import correct_background
from cwproc.pipeline.input_files import load_item
from cwproc.pipeline.product_units import concat_unit
from cwproc.pipeline.run import unit_products
from cwproc.pipeline.scan_chain import DayDecisions
from cwproc.pipeline.stream import stream_unit
from cwproc.sim.sample_data import StreamLineSpec, write_streamline_series
from cwproc.sim.stare import write_stare_series

#: a chunk of about three 180-ray files: many chunks, blocks that straddle them
SMALL_CHUNK = 3 * 180 * 40 * 8 * 6


def whole_day(folder, config, notes=None):
    """Products of the unit processed whole (the definition); its notes to ``notes``."""
    (unit,) = group_units(read_input(p, config) for p in sorted(folder.glob("*.hpl")))
    notes = [] if notes is None else notes
    scans = correct_background(concat_unit(unit), unit, config, notes)
    return process_scan_day(scans, config, notes)


def streamed_day(folder, config, chunk_bytes=SMALL_CHUNK, notes=None):
    (unit,) = group_units(read_input(p, config) for p in sorted(folder.glob("*.hpl")))
    for item in unit.inputs[::2]:  # half the files not held: read again when streamed
        item.dataset = None
    products = stream_unit(
        unit, config, notes, lambda item: load_item(item, config), chunk_bytes=chunk_bytes
    )
    assert products is not None, "the day was not streamed (a chunk chose differently)"
    return products


def assert_same_products(streamed: dict, whole: dict) -> None:
    """Same products, values and attributes (bit for bit)."""
    assert sorted(streamed) == sorted(whole)
    for name in whole:
        xr.testing.assert_identical(streamed[name], whole[name])
        assert streamed[name].attrs == whole[name].attrs, name


@pytest.fixture(scope="module")
def config():
    return load_config("streamline")


def test_streamed_vad_day_equals_whole_day(tmp_path, config):
    spec = StreamLineSpec(n_scans=25, scans_per_file=1, n_gates=40, seed=3)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    whole = whole_day(tmp_path / "day", config)
    streamed = streamed_day(tmp_path / "day", config)
    assert {"wind", "turbulence"} <= set(whole)
    # 25 scans in blocks of 10: the last block is the short one of the whole day
    assert whole["turbulence"].sizes["time"] == 3
    np.testing.assert_array_equal(whole["turbulence"]["n_scans"].values, [10, 10, 5])
    assert_same_products(streamed, whole)


def test_streamed_mixed_day_equals_whole_day(tmp_path, config):
    spec = StreamLineSpec(n_gates=40, seed=5)
    write_stare_series(
        tmp_path / "day", tmp_path / "truth.json", spec, scan="mixed", hours=0.5, vad_every_s=120
    )
    whole = whole_day(tmp_path / "day", config)
    streamed = streamed_day(tmp_path / "day", config)
    assert {"wind", "stare"} <= set(whole)
    assert_same_products(streamed, whole)


def test_chunk_larger_than_day_is_the_whole_run(tmp_path, config):
    spec = StreamLineSpec(n_scans=12, scans_per_file=2, n_gates=24, seed=7)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    assert_same_products(
        streamed_day(tmp_path / "day", config, chunk_bytes=1 << 40),
        whole_day(tmp_path / "day", config),
    )


def test_unit_products_streams_and_falls_back_identically(tmp_path, config, monkeypatch):
    """unit_products (run_unit) gives the whole-day products, streamed or not."""
    spec = StreamLineSpec(n_scans=14, scans_per_file=1, n_gates=24, seed=11)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    whole = whole_day(tmp_path / "day", config)
    (unit,) = group_units(read_input(p, config) for p in sorted((tmp_path / "day").glob("*.hpl")))
    assert_same_products(unit_products(unit, config, [], chunk_bytes=SMALL_CHUNK), whole)
    # a chunk deciding differently from the day: the day is processed whole
    monkeypatch.setattr(DayDecisions, "differences", lambda day, chunks: "azimuth step")
    (unit,) = group_units(read_input(p, config) for p in sorted((tmp_path / "day").glob("*.hpl")))
    assert stream_unit(unit, config, [], lambda i: load_item(i, config), SMALL_CHUNK) is None
    (unit,) = group_units(read_input(p, config) for p in sorted((tmp_path / "day").glob("*.hpl")))
    assert_same_products(unit_products(unit, config, [], chunk_bytes=SMALL_CHUNK), whole)


def test_streamed_background_correction_equals_whole_day(tmp_path, config):
    """Chunks matched to different background files: the SNR corrected as on the whole day."""
    spec = StreamLineSpec(n_scans=25, scans_per_file=1, n_gates=40, seed=13)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    ramp = 1.7e7 * (1.0 + 1e-5 * (np.arange(130) + 0.5) * 30.0)
    for name, scale in (
        ("Background_010624-115000.txt", 1.0),
        ("Background_010624-120400.txt", 1.01),
    ):
        text = "".join(f"{v * scale:.6f}\r\n" for v in ramp)
        (tmp_path / "day" / name).write_bytes(text.encode())
    whole_notes: list[str] = []
    whole = whole_day(tmp_path / "day", config, whole_notes)
    assert len(whole["wind"].attrs["background_files"]) == 2
    notes: list[str] = []
    assert_same_products(streamed_day(tmp_path / "day", config, notes=notes), whole)
    summary = [n for n in whole_notes if n.startswith("SNR of")]
    assert len(summary) == 1 and [n for n in notes if n.startswith("SNR")] == summary


def test_header_identity_groups_like_the_full_read(tmp_path, config):
    """retrieve groups .hpl files by header: same unit and first time as reading them."""
    from cwproc.pipeline import unit_key

    spec = StreamLineSpec(n_scans=4, scans_per_file=1, n_gates=24, start="2024-06-01T23:59:00")
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    for path in sorted((tmp_path / "day").glob("*.hpl")):
        full = read_input(path, config)
        light = read_input(path, config, identify_only=True)
        assert light.dataset is None and light.identity is not None
        assert unit_key(light) == unit_key(full)
        assert light.start == full.start
        assert light.sha256 == full.sha256


def test_each_input_is_checksummed_once(tmp_path, config, monkeypatch):
    """Grouping takes the checksum; the unit reads an unchanged file without a second one,
    and the products record the same checksum (provenance)."""
    import cwproc.pipeline.input_files as input_files
    from cwproc.io.netcdf import sha256_file

    spec = StreamLineSpec(n_scans=12, scans_per_file=1, n_gates=24, seed=17)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    paths = sorted((tmp_path / "day").glob("*.hpl"))
    calls: list[str] = []

    def counted(path):
        calls.append(str(path))
        return sha256_file(path)

    monkeypatch.setattr(input_files, "sha256_file", counted)
    items = [read_input(p, config, identify_only=True) for p in paths]
    (unit,) = group_units(items)
    streamed = unit_products(unit, config, [], chunk_bytes=SMALL_CHUNK)
    assert sorted(calls) == sorted(str(p) for p in paths)  # once each
    assert [i.sha256 for i in unit.inputs] == [sha256_file(p) for p in paths]
    assert_same_products(streamed, whole_day(tmp_path / "day", config))


def test_input_rewritten_after_grouping_is_caught(tmp_path, config):
    """A file written again after its checksum: compared again, a change fails the read."""
    import os

    from cwproc.errors import CwprocError

    spec = StreamLineSpec(n_scans=2, scans_per_file=1, n_gates=24, seed=19)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    first, second = sorted((tmp_path / "day").glob("*.hpl"))
    items = [read_input(p, config, identify_only=True) for p in (first, second)]
    os.utime(first, ns=(0, 10**18))  # touched, content the same: read as it is
    assert load_item(items[0], config)["radial_velocity"].shape[1] == 24
    text = second.read_bytes()
    second.write_bytes(text.replace(b"0.", b"1.", 1))  # same size, other content
    with pytest.raises(CwprocError, match="changed while cwproc was running"):
        load_item(items[1], config)


@pytest.mark.parametrize("ahead", [False, True])
def test_checksums_left_to_the_read_are_taken_by_it(tmp_path, config, monkeypatch, ahead):
    """Files identified by their header without a checksum (``checksum=False``, as
    ``cwproc retrieve`` groups them) get it from the streamed read of their data, with
    no further read of the file: each checksum is that of the file, hashed in the
    reading thread when reading ahead (beside the caller's numerical work), and the
    products are those of the whole day."""
    import threading

    import cwproc.pipeline.input_files as input_files
    from cwproc.io import halo_files
    from cwproc.io.netcdf import sha256_file

    hashed_in: list[str] = []
    hexdigest = halo_files._ReadBytes.hexdigest

    def recorded(self):
        hashed_in.append(threading.current_thread().name)
        return hexdigest(self)

    monkeypatch.setattr(halo_files._ReadBytes, "hexdigest", recorded)

    spec = StreamLineSpec(n_scans=12, scans_per_file=1, n_gates=24, seed=29)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    paths = sorted((tmp_path / "day").glob("*.hpl"))
    calls: list[str] = []
    monkeypatch.setattr(input_files, "sha256_file", lambda path: calls.append(str(path)) or "")
    items = [read_input(p, config, identify_only=True, checksum=False) for p in paths]
    assert all(i.sha256 is None and i.signature is not None for i in items)
    (unit,) = group_units(items)
    products = stream_unit(
        unit, config, [], lambda i: load_item(i, config), SMALL_CHUNK, read_ahead=ahead
    )
    assert calls == []  # taken by the plan's read of each file, not by another read
    assert [i.sha256 for i in unit.inputs] == [sha256_file(p) for p in paths]
    assert len(hashed_in) == len(paths)
    caller = threading.current_thread().name
    assert all(name.startswith("cwproc-chunk-ahead") == ahead for name in hashed_in)
    assert all((name == caller) != ahead for name in hashed_in)
    assert_same_products(products, whole_day(tmp_path / "day", config))


def test_a_streamed_file_is_opened_once(tmp_path, config, monkeypatch):
    """Grouped by its header without a checksum, each file of a streamed day is opened
    once by the unit: the plan's read gives its line count, its checksum and the data
    lines the parse takes."""
    from collections import Counter
    from pathlib import Path

    spec = StreamLineSpec(n_scans=12, scans_per_file=1, n_gates=24, seed=41)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    paths = sorted((tmp_path / "day").glob("*.hpl"))
    items = [read_input(p, config, identify_only=True, checksum=False) for p in paths]
    (unit,) = group_units(items)
    opened: Counter = Counter()
    real_open = Path.open

    def counting(self, *args, **kwargs):
        if self.suffix == ".hpl":
            opened[self.name] += 1
        return real_open(self, *args, **kwargs)

    monkeypatch.setattr(Path, "open", counting)
    products = stream_unit(
        unit, config, [], lambda i: load_item(i, config), SMALL_CHUNK, read_ahead=False
    )
    monkeypatch.undo()
    assert sorted(opened) == [p.name for p in paths] and set(opened.values()) == {1}
    assert_same_products(products, whole_day(tmp_path / "day", config))


def test_a_file_read_alone_gets_the_checksum_left_to_its_read(tmp_path, config):
    """An input identified without a checksum and read on its own (a chunk read file by
    file, a day processed whole) gets it from that read; one written since it was
    identified is refused, since what its header said may no longer hold."""
    import os

    from cwproc.errors import CwprocError
    from cwproc.io.netcdf import sha256_file

    spec = StreamLineSpec(n_scans=3, scans_per_file=1, n_gates=24, seed=31)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    first, second, third = sorted((tmp_path / "day").glob("*.hpl"))
    items = [
        read_input(p, config, identify_only=True, checksum=False) for p in (first, second, third)
    ]
    assert load_item(items[0], config)["radial_velocity"].shape[1] == 24
    assert items[0].sha256 == sha256_file(first)
    os.utime(second, ns=(0, 10**18))  # touched after identification
    with pytest.raises(CwprocError, match="changed while cwproc was running"):
        load_item(items[1], config)
    assert items[1].sha256 is None
    third.write_bytes(third.read_bytes().replace(b"0.", b"1.", 1))  # same size, other content
    with pytest.raises(CwprocError, match="changed while cwproc was running"):
        load_item(items[2], config)


def test_read_ahead_gives_the_serial_products_and_failures(tmp_path, config):
    """Files read in a second thread: the same products, notes and failure lines as one
    by one; a file damaged beyond its header is left out, named with its line."""
    from cwproc.pipeline.run import run_unit

    spec = StreamLineSpec(n_scans=25, scans_per_file=1, n_gates=40, seed=23)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    paths = sorted((tmp_path / "day").glob("*.hpl"))
    text = paths[7].read_bytes()
    paths[7].write_bytes(text[: len(text) - 300])  # the last ray cut short
    results = {}
    for ahead in (False, True):
        items = [read_input(p, config, identify_only=True) for p in paths]
        (unit,) = group_units(items)
        notes: list[str] = []
        products = stream_unit(
            unit, config, notes, lambda i: load_item(i, config), SMALL_CHUNK, read_ahead=ahead
        )
        results[ahead] = (products, notes, list(unit.failures))
    (products, notes, failures), (products_a, notes_a, failures_a) = results.values()
    assert_same_products(products_a, products)
    assert notes_a == notes and failures_a == failures
    assert len(failures) == 1 and failures[0].startswith(f"{paths[7]}:") and "line" in failures[0]
    assert products["wind"].sizes["time"] == 24
    (unit,) = group_units(read_input(p, config, identify_only=True) for p in paths)
    assert run_unit(unit, config).failures == failures


def test_read_ahead_hands_out_errors_in_order_and_stops(monkeypatch):
    """ReadAhead: results in order, at most max_bytes ahead, an error raised at its item,
    the thread stopped by close() (no hang); on by default (not in a pool's process),
    CWPROC_READ_AHEAD=0 turns it off."""
    import threading

    from cwproc.pipeline.stream import ReadAhead, read_ahead_enabled

    items = [object() for _ in range(6)]
    read_so_far: list[int] = []
    gate = threading.Event()

    def read(item):
        k = items.index(item)
        read_so_far.append(k)
        if k == 3:
            raise RuntimeError("bad file 3")
        return xr.Dataset({"v": ("x", np.zeros(100))})  # 800 bytes

    ahead = ReadAhead(items, read, max_bytes=1600)
    for _ in range(500):  # until the reader has read two (at most 5 s)
        if len(read_so_far) >= 2:
            break
        gate.wait(0.01)
    gate.wait(0.2)
    assert read_so_far == [0, 1]  # two datasets of 800 bytes: the budget is full
    for k in range(3):
        assert ahead.load(items[k])["v"].size == 100
    with pytest.raises(RuntimeError, match="bad file 3"):
        ahead.load(items[3])
    with pytest.raises(ValueError, match="in their order"):
        ahead.load(items[5])
    ahead.close()
    assert not ahead._thread.is_alive()
    monkeypatch.setenv("CWPROC_READ_AHEAD", "1")
    assert read_ahead_enabled() and not read_ahead_enabled(False)
    monkeypatch.setenv("CWPROC_READ_AHEAD", "0")
    assert not read_ahead_enabled()
    monkeypatch.delenv("CWPROC_READ_AHEAD")
    assert read_ahead_enabled()
    from cwproc.pipeline import stream_read

    # in a process of a pool (batch --workers N) the pool's processes take the cores
    monkeypatch.setattr(stream_read.multiprocessing, "parent_process", lambda: object())
    assert not read_ahead_enabled()
    monkeypatch.setenv("CWPROC_READ_AHEAD", "1")
    assert read_ahead_enabled()


def test_epsilon_by_groups_of_blocks_is_the_whole_fit(tmp_path, config, monkeypatch):
    """The dissipation-rate fit taken a few blocks at a time (bounded memory) gives the
    product of all blocks at once, attributes and counts of cells included; a cw probe
    (noise pooled over neighbouring blocks) is fitted whole."""
    import cwproc.stages.epsilon as epsilon
    from cwproc.physics.transfer import CWProbe

    spec = StreamLineSpec(n_scans=35, scans_per_file=1, n_gates=40, seed=3)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    fits = []
    fit = epsilon.estimate_epsilon
    monkeypatch.setattr(
        epsilon, "estimate_epsilon", lambda sf, **kw: fits.append(sf) or fit(sf, **kw)
    )
    monkeypatch.setattr(epsilon, "EPSILON_CELLS", 10**9)
    whole = whole_day(tmp_path / "day", config)["turbulence"]
    monkeypatch.setattr(epsilon, "EPSILON_CELLS", 40)  # 40 heights: one block a group
    assert len(epsilon.block_groups(fits[0], epsilon.PRESET_PROBE)) == 4
    assert epsilon.block_groups(fits[0], CWProbe(0.0013)) == [slice(0, 4)]
    asked = fits[0].copy(deep=True)
    del asked["structure_function"].attrs["n_scans_per_block"]  # then each group's own
    assert epsilon.block_groups(asked, epsilon.PRESET_PROBE) == [slice(0, 4)]
    grouped = whole_day(tmp_path / "day", config)["turbulence"]
    xr.testing.assert_identical(grouped, whole)
    assert list(grouped.variables) == list(whole.variables)
    for name in whole.variables:
        assert grouped[name].attrs == whole[name].attrs, name
        assert grouped[name].dtype == whole[name].dtype, name
    assert whole["integral_scale"].attrs["finite_outer_scale_cells"] > 0


def test_chunks_read_at_once_give_the_file_by_file_products(tmp_path, config, monkeypatch):
    """Chunks parsed into one dataset each: the products, notes, provenance and failure
    lines of the files read one by one, a damaged file left out alone with its line."""
    from cwproc.io import halo_files
    from cwproc.pipeline import stream

    spec = StreamLineSpec(n_scans=25, scans_per_file=1, n_gates=40, seed=29)
    write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)
    paths = sorted((tmp_path / "day").glob("*.hpl"))
    text = paths[11].read_bytes()
    paths[11].write_bytes(text[: len(text) - 300])  # the last ray cut short
    at_once = []
    real_run = halo_files.read_hpl_run

    def counted(plans):
        got = real_run(plans)
        at_once.append(got is not None)
        return got

    monkeypatch.setattr("cwproc.pipeline.stream_read.read_hpl_run", counted)
    results = []
    for possible in (True, False):
        monkeypatch.setattr(stream, "chunk_reading_possible", lambda unit, cfg, p=possible: p)
        (unit,) = group_units(read_input(p, config, identify_only=True) for p in paths)
        notes: list[str] = []
        products = stream_unit(unit, config, notes, lambda i: load_item(i, config), SMALL_CHUNK)
        identities = [(i.identity.attrs, i.identity.time) for i in unit.inputs]
        results.append((products, notes, list(unit.failures), identities))
    (products, notes, failures, ids), (products_1, notes_1, failures_1, ids_1) = results
    # the chunk with the damaged file alone is read file by file
    assert at_once.count(False) == 1 and at_once.count(True) == len(at_once) - 1 >= 3
    assert_same_products(products, products_1)
    assert notes == notes_1 and failures == failures_1
    assert len(failures) == 1 and failures[0].startswith(f"{paths[11]}:") and "line" in failures[0]
    assert len(ids) == len(ids_1) == 24
    for (attrs, time), (attrs_1, time_1) in zip(ids, ids_1, strict=True):
        assert attrs == attrs_1
        np.testing.assert_array_equal(time, time_1)
    assert products["wind"].attrs["source_files"] == products_1["wind"].attrs["source_files"]
    assert products["wind"].sizes["time"] == 24


def test_read_inputs_keeps_the_order_and_hands_errors_in_place(monkeypatch):
    """read_inputs: items in the order of the paths whatever order the threads finish
    in, a file's error in its place, at most 2 * threads inputs read whole ahead; the
    inputs known from their header identified in the caller's thread."""
    import threading
    import time

    from cwproc.errors import InputFileError
    from cwproc.io import Format
    from cwproc.pipeline import retrieve
    from cwproc.pipeline.input_files import Examined

    lock = threading.Lock()
    started: list[str] = []
    taken = 0
    ahead: list[int] = []
    caller = threading.current_thread()
    identified_in: set[threading.Thread] = set()

    def fake_identify(path, config):
        identified_in.add(threading.current_thread())
        if path == "f4":
            raise InputFileError(path, "not a regular file")
        if int(path[1:]) % 3 == 0:
            return f"header {path}"
        return Examined(Format.HPL, (0, 0, 0, 0, 0))  # read whole

    def fake_read(path, config, *, examined):
        assert examined.format is Format.HPL  # not examined again
        with lock:
            started.append(path)
            ahead.append(len(started) - taken)
        time.sleep(0.002 * (len(path) % 3))  # later ones may finish first
        if path == "f7":
            raise InputFileError(path, "line 3: not a number")
        if path == "f11":
            raise KeyError("a reader bug")
        return f"item {path}"

    monkeypatch.setattr(retrieve, "identify_input", fake_identify)
    monkeypatch.setattr(retrieve, "read_input", fake_read)
    paths = [f"f{k}" for k in range(20)]
    got = []
    for path, item in retrieve.read_inputs(paths, None, threads=2):
        got.append((path, item))
        with lock:
            taken += 1
    assert [p for p, _ in got] == paths
    assert identified_in == {caller}
    assert isinstance(got[4][1], InputFileError) and "regular" in str(got[4][1])
    assert isinstance(got[7][1], InputFileError) and "line 3" in str(got[7][1])
    assert isinstance(got[11][1], KeyError)
    whole = [p for p in paths if int(p[1:]) % 3 and p != "f4"]
    assert sorted(started) == sorted(whole)
    assert [item for p, item in got if p not in ("f4", "f7", "f11")] == [
        f"header {p}" if int(p[1:]) % 3 == 0 else f"item {p}"
        for p in paths
        if p not in ("f4", "f7", "f11")
    ]
    assert max(ahead) <= 2 * 2 + 1


def test_read_inputs_identifies_hpl_headers_in_the_callers_thread(tmp_path, monkeypatch):
    """``.hpl`` files known from their header are identified by the caller's thread
    (nothing handed to the reading threads), with no checksum and no dataset (the
    unit's read of the data takes both); a header cut short is read whole, by a thread,
    and its reader's error handed back in its place."""
    from cwproc.pipeline import retrieve

    spec = StreamLineSpec(n_scans=4, scans_per_file=1, n_gates=24, seed=3)
    paths = write_streamline_series(tmp_path / "day", tmp_path / "truth.json", spec)[:-1]
    whole: list = []
    real_read_one = retrieve._read_one
    monkeypatch.setattr(
        retrieve, "_read_one", lambda p, c, e: whole.append(p) or real_read_one(p, c, e)
    )
    got = list(retrieve.read_inputs(paths, load_config("streamline"), threads=2))
    assert [p for p, _ in got] == paths and not whole
    for _, item in got:
        assert item.identity is not None and item.dataset is None and item.sha256 is None
    broken = tmp_path / "day" / "broken.hpl"
    broken.write_bytes(paths[0].read_bytes()[:200])  # cut inside the header
    got = list(retrieve.read_inputs([broken], load_config("streamline"), threads=2))
    assert whole == [broken] and isinstance(got[0][1], Exception)
    assert "broken.hpl" in str(got[0][1])


def test_parts_joined_like_xarray_concat(tmp_path, config, monkeypatch):
    """The day's wind rows, structure functions and stares joined from the chunks'
    pieces (``chain.join``, ``xr.concat`` without alignment or comparisons): what the
    default ``xr.concat`` gives (values, attributes, encodings, variable order)."""
    from cwproc.pipeline import scan_chain as chain

    spec = StreamLineSpec(n_gates=24, seed=37)
    write_stare_series(
        tmp_path / "day", tmp_path / "truth.json", spec, scan="mixed", hours=1.0, vad_every_s=60
    )
    items = [read_input(p, config) for p in sorted((tmp_path / "day").glob("*.hpl"))]
    (unit,) = group_units(items)
    pieces: list[tuple[list, str]] = []
    real_append = chain.Rows.append

    def recording(rows, part):
        if rows.first is None:  # a new day's (or a carry's) rows
            rows.recorded = []
            pieces.append((rows.recorded, rows.dim))
        rows.recorded.append(part)
        return real_append(rows, part)

    monkeypatch.setattr(chain.Rows, "append", recording)
    assert stream_unit(unit, config, [], lambda i: load_item(i, config), SMALL_CHUNK)
    joined = [(parts, dim) for parts, dim in pieces if len(parts) > 1]
    assert {dim for _, dim in joined} >= {"time", "ray"}  # winds, sfs, stares and carries
    for parts, dim in joined:
        ours = chain.Rows.of(parts, dim)
        theirs = xr.concat(parts, dim=dim, combine_attrs="override")
        assert ours.identical(theirs)
        assert list(ours.variables) == list(theirs.variables)
        assert all(ours[k].encoding == theirs[k].encoding for k in theirs.variables)
    parts, dim = next((p, d) for p, d in joined if d == "time")
    shifted = [parts[0], parts[1].assign_coords(height=parts[1]["height"] + 1.0)]
    with pytest.raises(chain.PartsDiffer, match="another height"):
        chain.Rows.of(shifted, dim)
    with pytest.raises(chain.PartsDiffer, match="other variables"):
        chain.Rows.of([parts[0], parts[1].assign(extra=((), 1.0))], dim)
