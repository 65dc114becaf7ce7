"""The vectorised root search of the outer-scale fit (stage ``epsilon``).

:func:`cwproc.physics.root_search.replayed_root` must give the roots of the
bisections it replaces bit for bit wherever the residual crosses zero once in the
bracket, from three evaluations instead of seven, and bisect for real where its guess
misses; on residuals whose roots are known exactly.
"""

import numpy as np
import pytest

from cwproc.physics.root_search import bracket_root, replayed_root

FACTOR, STEPS = 2.0, 6
RNG = np.random.default_rng(12)
START = 10 ** RNG.uniform(1.5, 3.3, 400)  # known roots, m


def counted(residual_of):
    """``residual_of`` that counts the evaluations of the residuals it makes."""
    calls = []

    def wrapped(index):
        inner = residual_of(index)

        def residual(big_l):
            calls.append(big_l.shape)
            return inner(big_l)

        return residual

    return wrapped, calls


def curved_residual_of(roots, curvature=0.4, floor=None):
    """Rising parabolas in log L_V through ``roots``; NaN below ``floor`` (m)."""

    def residual_of(index):
        def residual(big_l):
            x = np.log(big_l / roots[index][:, None])
            r = x + curvature * x**2
            if floor is not None:
                r = np.where(big_l < floor[index][:, None], np.nan, r)
            return r

        return residual

    return residual_of


def bisected(residual_of, start):
    nodes = start[:, None] * np.array([1 / FACTOR, 1.0, FACTOR])
    return bracket_root(residual_of(np.arange(start.size)), nodes, STEPS)


def test_bracket_root_finds_a_known_root():
    roots = START * RNG.uniform(0.6, 1.6, START.size)
    root, has_root, below, slope = bisected(curved_residual_of(roots), START)
    assert has_root.all() and not below.any()
    # a bracket of a factor 2 halved 6 times (1.1 %), then the chord: far better
    np.testing.assert_allclose(root, roots, rtol=2e-4)
    # the chord's slope over the last bracket is the derivative at the root, 1
    np.testing.assert_allclose(slope, 1.0, rtol=0.02)


@pytest.mark.parametrize("spread", [0.02, 0.2, 0.6])
def test_replay_equals_the_bisections_bit_for_bit(spread):
    # the statistics changed: the roots moved by up to a factor exp(spread); the slope
    # known at the start is that of the unmoved residual (1)
    roots = START * np.exp(RNG.uniform(-spread, spread, START.size))
    residual_of, calls = counted(curved_residual_of(roots))
    expected = bisected(residual_of, START)
    n_bisect = len(calls)
    calls.clear()
    root, has_root, below = replayed_root(residual_of, START, np.ones(START.size), FACTOR, STEPS)
    np.testing.assert_array_equal(root, expected[0])
    np.testing.assert_array_equal(has_root, expected[1])
    np.testing.assert_array_equal(below, expected[2])
    assert n_bisect == STEPS + 1
    # nodes, the secant step, the two ends; then the cells whose guess fell in another
    # final interval (the secant's error against its width, 1.1 %) bisected again
    assert [shape[0] for shape in calls[:3]] == [START.size] * 3
    again = calls[3][0] if len(calls) > 3 else 0
    assert again <= {0.02: 0, 0.2: 0.05, 0.6: 0.5}[spread] * START.size


def test_a_residual_not_finite_at_a_node_keeps_its_meaning():
    # the model's variance not positive below 0.7 of the known root (NaN there, at the
    # lowest node): the scan sees no rising sign change, as the bisections' scan does
    roots = START * RNG.uniform(0.75, 0.95, START.size)
    residual_of = curved_residual_of(roots, floor=0.7 * START)
    expected = bisected(residual_of, START)
    got = replayed_root(residual_of, START, np.ones(START.size), FACTOR, STEPS)
    assert not expected[1].any()
    np.testing.assert_array_equal(got[1], expected[1])
    np.testing.assert_array_equal(got[2], expected[2])


def test_a_jump_is_bisected_for_real():
    # the residual jumps by 0.3 through zero at the moved root (the noise rule of the
    # fit switching there): the secant guess misses, the replayed ends contradict it
    roots = START * 1.1

    def residual_of(index):
        def residual(big_l):
            x = np.log(big_l / roots[index][:, None])
            return x + np.where(x >= 0, 0.3, -0.3)

        return residual

    counting, calls = counted(residual_of)
    expected = bisected(residual_of, START)
    got = replayed_root(counting, START, np.ones(START.size), FACTOR, STEPS)
    for a, b in zip(expected[:3], got, strict=True):
        np.testing.assert_array_equal(a, b)
    assert len(calls) == 3 + STEPS  # every cell bisected again


def test_two_crossings_follow_the_known_root():
    # rising through 0 at 0.8 and at 1.02 of the known root, a drop between (the noise
    # rule switching at 0.9): the bisections may take the lower crossing, the replay
    # keeps the branch of the known root, where its secant steps lead
    def residual_of(index):
        def residual(big_l):
            ratio = big_l / START[index][:, None]
            return np.where(ratio < 0.9, np.log(ratio / 0.8), np.log(ratio / 1.02))

        return residual

    root, has_root, _ = replayed_root(residual_of, START, np.ones(START.size), FACTOR, STEPS)
    assert has_root.all()
    np.testing.assert_allclose(root, 1.02 * START, rtol=1e-3)
