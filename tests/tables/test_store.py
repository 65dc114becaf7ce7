"""The disk cache of the table store (cwproc.tables.store) and its users."""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

from cwproc.physics import removed_share
from cwproc.tables import removed_share as stored_share
from cwproc.tables import store as disk_cache


def _counted(values: np.ndarray):
    calls = []

    def compute() -> dict[str, np.ndarray]:
        calls.append(1)
        return {"values": values.copy()}

    return compute, calls


def _finite(arrays: dict[str, np.ndarray]) -> bool:
    return "values" in arrays and bool(np.isfinite(arrays["values"]).all())


def test_arrays_are_computed_once_and_read_back_bit_for_bit(tmp_path):
    values = np.random.default_rng(1).normal(size=(7, 25))
    compute, calls = _counted(values)
    params = {"a": 1.5, "model": "von_karman", "version": 1}
    first = disk_cache.cached_arrays("test", params, compute, _finite, tmp_path)
    second = disk_cache.cached_arrays("test", params, compute, _finite, tmp_path)
    assert len(calls) == 1
    assert second["values"].tobytes() == first["values"].tobytes() == values.tobytes()
    (path,) = tmp_path.glob("test-*.npz")
    assert path.name == f"test-{disk_cache.parameter_key(params)}.npz"
    assert not list(tmp_path.glob(".*part"))  # no temporary file left behind


def test_other_parameters_get_their_own_file(tmp_path):
    compute, calls = _counted(np.ones(3))
    disk_cache.cached_arrays("test", {"a": 1}, compute, _finite, tmp_path)
    disk_cache.cached_arrays("test", {"a": 2}, compute, _finite, tmp_path)
    assert len(calls) == 2
    assert len(list(tmp_path.glob("test-*.npz"))) == 2


@pytest.mark.parametrize("damage", ["truncated", "garbage", "other_key", "not_finite"])
def test_a_damaged_or_foreign_file_is_computed_again(tmp_path, damage):
    values = np.arange(6.0)
    compute, calls = _counted(values)
    params = {"a": 3}
    path = disk_cache.cache_path(tmp_path, "test", disk_cache.parameter_key(params))
    if damage == "other_key":
        disk_cache.save_arrays(path, {"key": np.array("0" * 64), "values": values + 1})
    elif damage == "not_finite":
        key = disk_cache.parameter_key(params)
        disk_cache.save_arrays(path, {"key": np.array(key), "values": np.full(6, np.nan)})
    else:
        disk_cache.cached_arrays("test", params, compute, _finite, tmp_path)
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2] if damage == "truncated" else b"\x00" * 64)
        calls.clear()
    got = disk_cache.cached_arrays("test", params, compute, _finite, tmp_path)
    assert len(calls) == 1
    np.testing.assert_array_equal(got["values"], values)
    # and the file now holds the good arrays
    again = disk_cache.load_arrays(path, disk_cache.parameter_key(params))
    np.testing.assert_array_equal(again["values"], values)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes to read-only folders")
def test_an_unwritable_folder_only_costs_the_computation(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        compute, calls = _counted(np.ones(2))
        for _ in range(2):
            got = disk_cache.cached_arrays("test", {"a": 1}, compute, _finite, folder)
            np.testing.assert_array_equal(got["values"], np.ones(2))
        assert len(calls) == 2
    finally:
        folder.chmod(0o700)


def test_a_folder_in_place_of_the_cache_file_only_costs_the_computation(tmp_path):
    params = {"a": 4}
    path = disk_cache.cache_path(tmp_path, "test", disk_cache.parameter_key(params))
    path.mkdir(parents=True)  # neither readable nor replaceable as a file
    compute, calls = _counted(np.ones(2))
    got = disk_cache.cached_arrays("test", params, compute, _finite, tmp_path)
    np.testing.assert_array_equal(got["values"], np.ones(2))
    assert len(calls) == 1


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_the_removed_share_curve_from_the_cache_is_the_computed_one(tmp_path, model):
    """The curve read back from disk is the computed one bit for bit, so retrievals do
    not change with the cache (Banakh et al. (1999), eqs. 15-16 evaluated once)."""
    cached = stored_share.stored_curve.__wrapped__  # past the in-process cache
    log_x, share = removed_share.removed_share_curve(75.0, model)
    for _ in range(2):  # computed and stored, then read from the file
        got_x, got = cached(75.0, model, os.fspath(tmp_path))
        assert got.tobytes() == share.tobytes() and got_x.tobytes() == log_x.tobytes()
    assert len(list(tmp_path.glob("removed-share-*.npz"))) == 1
    # the share of a circle is a fraction of the variance, zero for a point-sized circle
    assert np.all((share >= 0.0) & (share < 1.0))
    ratio, mu = np.array([0.02, 0.5, 3.0]), np.array([0.0, 1.0, 4.0])
    with_cache = stored_share.mean_removed_share(ratio, 75.0, model, mu, tmp_path)
    without = stored_share.mean_removed_share(ratio, 75.0, model, mu)
    assert with_cache.tobytes() == without.tobytes()


def test_the_code_digest_follows_the_modules_a_table_uses(tmp_path):
    """The cache key holds a hash of the code of the physics modules the build uses
    (the closure of its imports): a change of one of them gives a new key, a change of
    a module the tables do not use does not."""
    src = disk_cache.PHYSICS_FOLDER
    folder = tmp_path / "physics"
    shutil.copytree(src, folder, ignore=shutil.ignore_patterns("__pycache__"))
    before = disk_cache.code_digest("cwproc.physics.atable", str(folder))
    assert before == disk_cache.code_digest("cwproc.physics.atable", str(src))
    with (folder / "vad_errors.py").open("a") as fh:  # not used by the tables
        fh.write("\n# unrelated\n")
    assert disk_cache.code_digest.__wrapped__("cwproc.physics.atable", str(folder)) == before
    with (folder / "spectra.py").open("a") as fh:  # used through afunctions and others
        fh.write("\n# changed\n")
    assert disk_cache.code_digest.__wrapped__("cwproc.physics.atable", str(folder)) != before
    share = disk_cache.code_digest.__wrapped__("cwproc.physics.removed_share", str(folder))
    assert share != disk_cache.code_digest("cwproc.physics.removed_share", str(src))


def test_the_code_digest_does_not_depend_on_where_the_package_is(tmp_path):
    """The digest hashes the modules by their dotted names and texts, not their paths:
    a copy of the physics sources elsewhere (another checkout, a wheel) gives the key
    of the tables shipped from this one."""
    folder = tmp_path / "elsewhere" / "deeper" / "physics"
    shutil.copytree(disk_cache.PHYSICS_FOLDER, folder, ignore=shutil.ignore_patterns("__pycache__"))
    for module in ("cwproc.physics.atable", "cwproc.physics.removed_share"):
        assert disk_cache.code_digest.__wrapped__(module, str(folder)) == disk_cache.code_digest(
            module
        )


def test_the_default_folder_follows_the_environment(tmp_path, monkeypatch):
    """The one place that reads the environment for the cache reads it at each call."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert disk_cache.default_cache_dir() == tmp_path / "cwproc"
    assert disk_cache.cache_path(None, "atable", "k") == tmp_path / "cwproc" / "atable-k.npz"
