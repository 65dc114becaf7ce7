"""Shared fixtures: where the real instrument files are (``../shared/real_data``)."""

from __future__ import annotations

import itertools
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# CI (CI=true) runs the property tests derandomised: a red build then always means a
# reproducible defect, never an unlucky draw; developers keep random exploration.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

#: the one temporary cache folder of a test session (tables, removed-share curves): set
#: at import by the controller, inherited by pytest-xdist workers (spawned later), so
#: that no test reads or writes the user's ~/.cache/cwproc
TEST_CACHE_VARIABLE = "CWPROC_TEST_CACHE"
_OWN_CACHE: str | None = None
if not os.environ.get(TEST_CACHE_VARIABLE):
    _OWN_CACHE = tempfile.mkdtemp(prefix="cwproc-test-cache-")
    os.environ[TEST_CACHE_VARIABLE] = _OWN_CACHE
os.environ["XDG_CACHE_HOME"] = os.environ[TEST_CACHE_VARIABLE]


#: BLAS/OpenMP thread pools of each pytest-xdist worker: one thread, as many workers as
#: cores already keep every core busy; two workers with a pool of two threads each on two
#: cores would make the pools' threads wait for each other (OpenBLAS spins while it waits)
WORKER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def pytest_configure(config):
    """The controller of a parallel run (``-n``) sets the workers' thread pools to one
    thread before it spawns them (they inherit its environment); a setting of the user's
    own is kept."""
    if getattr(config.option, "numprocesses", None) and not hasattr(config, "workerinput"):
        for name in WORKER_THREAD_VARIABLES:
            os.environ.setdefault(name, "1")


#: CPU seconds (one core) of the tests that take more than about 5 s, by test function
#: (the most costly of its parameters): a scheduling hint only (:func:`_heaviest_first`),
#: a test not named here runs where it falls. The fresh-environment test spends as much
#: again waiting for the disk and its subprocesses, hence early in the run.
HEAVY_TESTS = {
    "test_exact_statistics_eps_is_unbiased_and_its_error_bar_calibrated": 55.0,
    "test_point_beams_give_the_factor_of_the_exact_covariance": 29.0,
    "test_error_bars_of_a_sector_swept_back_to_back_match_the_scatter": 41.0,
    "test_zephir300_preset_reads_the_simulated_zephir_scans": 44.0,
    "test_new_user_follows_the_readme": 40.0,
    "test_swept_von_karman_table_matches_exact_pairs": 26.0,
    "test_von_karman_coarse_scans_recover_eps_and_outer_scale": 12.0,
    "test_swept_table_matches_exact_pairs_on_the_circle_and_per_node": 7.0,
    "test_coarse_continuous_sweep_converges": 7.0,
    "test_swept_rays_seen_at_their_own_times": 5.0,
    "test_the_variance_error_grows_by_the_correlated_circle_factor_at_mu_1": 14.0,
    "test_eps_and_noise_hold_when_the_snr_misstates_the_noise": 4.0,
}


def _heaviest_first(items: list, workers: int, chunk: int) -> list:
    """``items`` reordered so that pytest-xdist's ``load`` schedule starts the heavy
    tests first, spread over the workers.

    The schedule sends each of the ``workers`` its first ``chunk`` items (in collection
    order) and the rest on demand, so a test collected late (the fresh-environment test of
    ``test_readme.py``) would start last and keep one worker busy alone at the end. Here
    the heavy tests (:data:`HEAVY_TESTS`) are dealt longest first to the worker with the
    least heavy work so far, and each worker's first chunk starts with its share.
    """
    heavy = [i for i in items if getattr(i, "originalname", i.name) in HEAVY_TESTS]
    if not heavy or workers < 2:
        return items
    heavy.sort(key=lambda i: -HEAVY_TESTS[getattr(i, "originalname", i.name)])
    loads, shares = [0.0] * workers, [[] for _ in range(workers)]
    for item in heavy:
        k = loads.index(min(loads))
        shares[k].append(item)
        loads[k] += HEAVY_TESTS[getattr(item, "originalname", item.name)]
    chosen = {id(i) for i in heavy}
    rest = iter([i for i in items if id(i) not in chosen])
    ordered = []
    for share in shares:
        ordered += share
        ordered += itertools.islice(rest, max(chunk - len(share), 0))
    return ordered + list(rest)


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node):
    """pytest-xdist: tell each worker the controller's schedule (a worker's own ``dist``
    option is ``no``)."""
    node.workerinput["cwproc_dist"] = node.config.getoption("dist")


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items):
    """The tests of ``../shared`` deselected when it is absent (:func:`_deselect_shared`);
    then, in a pytest-xdist worker of a ``load`` run, the heavy tests first
    (:func:`_heaviest_first`), after every deselection (``-m`` too), so that the chunks
    are those of the schedule."""
    _deselect_shared(config, items)
    worker = getattr(config, "workerinput", None)
    if worker is None or worker.get("cwproc_dist") != "load":
        return
    workers = int(worker["workercount"])
    # the first chunk of each worker, as xdist.scheduler.LoadScheduling.schedule makes it
    chunk = len(items) // workers // 4
    if config.getoption("maxschedchunk", None):
        chunk = min(chunk, config.getoption("maxschedchunk"))
    items[:] = _heaviest_first(items, workers, max(chunk, 2))


def pytest_sessionfinish(session, exitstatus):
    """The controller (the process that made the folder) removes the session's cache."""
    if _OWN_CACHE is not None and not hasattr(session.config, "workerinput"):
        shutil.rmtree(_OWN_CACHE, ignore_errors=True)


REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("CWPROC_SHARED", REPO.parent / "shared"))
REAL_DATA = SHARED / "real_data"
REFERENCE = SHARED / "reference"


@pytest.fixture(scope="session")
def real_data() -> Path:
    """The folder of real instrument files; skips the test when it is absent."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real instrument files not available: {REAL_DATA} does not exist")
    return REAL_DATA


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    """The folder of published/independent reference values; skips when absent."""
    if not REFERENCE.is_dir():
        pytest.skip(f"reference values not available: {REFERENCE} does not exist")
    return REFERENCE


#: fixtures that need the project's own files under ../shared (not shipped)
SHARED_FIXTURES = {"real_data": REAL_DATA, "reference_dir": REFERENCE}


def _deselect_shared(config, items):
    """Without ../shared (every user's case) its tests are deselected, not skipped one by
    one: the readers are covered by the shipped samples (tests/sim/test_sample_data.py)."""
    missing = {name for name, path in SHARED_FIXTURES.items() if not path.is_dir()}
    if not missing:
        return
    keep, drop = [], []
    for item in items:
        (drop if missing & set(getattr(item, "fixturenames", ())) else keep).append(item)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep


def _absent_note() -> str | None:
    if SHARED.is_dir():
        return None
    return (
        f"cwproc: {SHARED} is absent: tests of the project's real instrument files and "
        "reference values are deselected (the shipped samples cover every reader)"
    )


def pytest_report_header(config):
    return _absent_note()


def pytest_terminal_summary(terminalreporter):
    """The note once more at the end: ``-q`` hides the header, and with ``-n auto`` the
    workers deselect, so the summary line does not count the deselected tests."""
    note = _absent_note()
    if note:
        terminalreporter.write_line(note)


def _check(path: Path, test: str) -> dict:
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    out = path.with_suffix(f".{test.replace(':', '_')}.json")
    ComplianceChecker.run_checker(
        os.fspath(path),
        [test],
        verbose=0,
        criteria="normal",
        output_filename=os.fspath(out),
        output_format="json",
    )
    result = next(iter(json.loads(out.read_text()).values()))
    out.unlink()
    return result


def _compliance(path: Path) -> tuple[list[str], float]:
    """(CF-1.10 high-priority failures, ACDD-1.3 score as a fraction) of a NetCDF file."""
    cf = _check(Path(path), "cf:1.10")
    acdd = _check(Path(path), "acdd:1.3")
    high = [f"{c['name']}: {m}" for c in cf["high_priorities"] for m in c["msgs"]]
    return high, acdd["scored_points"] / acdd["possible_points"]


@pytest.fixture(scope="session")
def compliance():
    """The IOOS compliance checker as a function: path -> (CF high failures, ACDD score)."""
    pytest.importorskip("compliance_checker")
    return _compliance


def _chromatic_pixels(fig) -> list[int]:
    """Coloured (chromatic) pixels inside each data panel, legends and colour bars aside.

    Axes, text and the grey background of gaps are achromatic; data are drawn in colour.
    """
    for ax in fig.axes:
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(float) / 255.0
    chroma = img.max(axis=-1) - img.min(axis=-1)
    counts = []
    height = img.shape[0]
    for ax in fig.axes:
        if hasattr(ax, "_colorbar"):
            continue
        bb = ax.get_window_extent()
        rows = slice(int(height - bb.y1) + 2, int(height - bb.y0) - 2)
        cols = slice(int(bb.x0) + 2, int(bb.x1) - 2)
        counts.append(int((chroma[rows, cols] > 0.15).sum()))
    return counts


@pytest.fixture
def data_pixels():
    """Counts of coloured pixels per data panel of a matplotlib figure (the screenshot
    check of tests/test_plots.py and tests/test_plots_stare.py)."""
    return _chromatic_pixels
