"""cwproc's sonic screening against a reference implementation, EC-PeT (issue 36).

``data/sonic_reference_ecpet.json`` holds what EC-PeT 2.1.0b1 (PyPI ``ecpet``,
C. Drüe, Universität Trier) finds on the series of ``sonic_series.py``; it was written
by ``tools/sonic_reference_ecpet.py`` (EC-PeT's settings there: VM97's published
constants; Mauder et al.'s 7 MAD/0.6745). EC-PeT is not needed to run these tests.

Tolerances:

* despiking: the same samples, exactly. Known, explained differences, asserted as such:
  EC-PeT's Mauder test has no run-length rule, so it also takes the samples of the
  20-sample burst that cwproc (like EddyPro, runs of at most 3) keeps; and EC-PeT's
  Vickers & Mahrt test goes on for up to 10 passes while outliers it has not removed
  remain (the burst), so at 5 sigma its raised thresholds split the burst into short
  runs it then takes; cwproc stops, as VM97 and EddyPro do, at the first pass without
  a new spike. Nothing outside the burst differs.
* steady-state deviation RN: 0.1 percentage point. EC-PeT's covariances are the
  pandas sample ones (divisor n - 1), cwproc's the population ones (divisor n): the
  mean of the 6 sub-window covariances moves relative to the window's by 1/m - 1/N
  (m = N/6), 0.03 % of the ratio here.
* ITC models: 1e-12 relative (the same closed forms).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import sonic_series as ss

from cwproc.physics import sonic_turbulence as st

REF = json.loads((Path(__file__).parent / "data" / "sonic_reference_ecpet.json").read_text())
BURST = set(range(9000, 9020))


def test_reference_was_made_by_the_tool_and_version_stated():
    assert REF["reference"] == "EC-PeT" and REF["version"] == "2.1.0b1"
    assert (Path(__file__).resolve().parents[2] / REF["script"]).is_file()


@pytest.mark.parametrize("case", sorted(ss.spiked_cases()))
def test_the_series_are_the_ones_the_reference_saw(case):
    y, injected = ss.spiked_cases()[case]
    assert ss.fingerprint(y) == pytest.approx(REF["despiking"][case]["fingerprint"], rel=1e-12)
    assert np.flatnonzero(injected).tolist() == REF["despiking"][case]["injected"]


@pytest.mark.parametrize("case", sorted(ss.spiked_cases()))
def test_vickers_mahrt_finds_the_spikes_ec_pet_finds(case):
    y, _ = ss.spiked_cases()[case]
    ref = REF["despiking"][case]
    _, spikes = st.despike_vickers_mahrt(y, ss.RATE)  # u, v: 3.5 sigma
    assert np.flatnonzero(spikes).tolist() == ref["vm97_u"]
    _, spikes = st.despike_vickers_mahrt(y, ss.RATE, factor=st.VM97_FACTOR_W)  # w
    ours, theirs = set(np.flatnonzero(spikes).tolist()), set(ref["vm97_w"])
    assert ours <= theirs
    assert theirs - ours <= BURST  # EC-PeT's extra passes split the burst (module doc)


@pytest.mark.parametrize("case", sorted(ss.spiked_cases()))
def test_mauder_finds_the_spikes_ec_pet_finds(case):
    y, _ = ss.spiked_cases()[case]
    _, spikes = st.despike_mauder(y)
    ours, theirs = set(np.flatnonzero(spikes).tolist()), set(REF["despiking"][case]["mad"])
    assert ours - BURST == theirs - BURST
    assert not ours & BURST  # a 20-sample burst is not a spike (runs of at most 3)


@pytest.mark.parametrize("case", sorted(ss.flux_cases()))
def test_steady_state_deviation_matches_ec_pet(case):
    u, w = ss.flux_cases()[case]
    ref = REF["stationarity_pct"][case]
    assert ss.fingerprint(u) + ss.fingerprint(w) == pytest.approx(ref["fingerprint"], rel=1e-12)
    assert st.stationarity_deviation(u, w) == pytest.approx(ref["rn"], abs=0.1)


def test_flags_of_the_reference_deviations():
    """The 0-1-2 flag of the reference's RN with a passing ITC: the steady flux and the
    flux that changes sign (whose sub-window means are steady: the test cannot see it)
    0, the step and the opposite ramp 1, the same-signed ramp 2."""
    flags = {k: st.foken_flag(v["rn"], 10.0) for k, v in REF["stationarity_pct"].items()}
    assert flags == {
        "steady": 0,
        "flux_changes_sign": 0,
        "step_u": 1,
        "ramp_opposite": 1,
        "ramp_same": 2,
    }


def test_itc_models_match_ec_pet():
    itc = REF["itc"]
    f = st.coriolis_parameter(itc["latitude_deg"])
    assert f == pytest.approx(itc["coriolis_s-1"], rel=1e-12)
    for pt in itc["points"]:
        zl, ustar = pt["zl"], pt["ustar"]
        w = st.itc_model_sigma_w(zl, 10.0, itc["latitude_deg"], ustar)
        u = st.itc_model_sigma_u(zl, itc["latitude_deg"], ustar)
        assert w == pytest.approx(pt["sigma_w_over_ustar"], rel=1e-12), (zl, ustar)
        assert u == pytest.approx(pt["sigma_u_over_ustar"], rel=1e-12), (zl, ustar)
