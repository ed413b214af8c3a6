"""Near-ties decided the same on every machine (``findme_core.geometry.ties``), and the boundary search
deciding its ties by them."""

import json

import numpy as np
import pytest

from findme_core.geometry import ties
from findme_core.single.search import Events, best_paths
from tests import numeric_envs


def _noisy(v, seed):
    """``v`` with a last-bit difference on each value, as another BLAS kernel gives."""
    rng = np.random.default_rng(seed)
    v = np.asarray(v, float)
    return v + rng.choice([-1.0, 0.0, 1.0], v.shape) * np.spacing(np.abs(v) + 1e-300) * 4


def test_argmax_takes_the_lowest_index_among_near_ties():
    v = np.array([1.0, 3.0, 3.0 + 1e-13, 2.0, 3.0 - 1e-13])
    assert ties.argmax(v) == 1 and np.argmax(v) == 2
    for seed in range(20):
        assert ties.argmax(_noisy(v, seed)) == 1
    assert ties.argmax([1.0, 3.0, 3.001]) == 2          # a real difference wins
    assert ties.argmin([2.0, 1.0 + 1e-14, 1.0, 5.0]) == 1
    assert ties.argmax(np.array([[0.0, 5.0], [5.0, 1.0]])) == 1   # flattened, like np.argmax
    assert ties.argmax([np.nan, 1.0, np.nan]) == 1 and ties.argmax([np.nan, np.nan]) == 0
    assert ties.argmax([-np.inf, 2.0, np.inf, np.inf]) == 2
    assert ties.argmax([1.0, 1.0 + 1e-4], atol=1e-3) == 0     # a caller's own tolerance
    with pytest.raises(ValueError):
        ties.argmax([])


def test_order_keeps_near_equal_values_in_index_order():
    v = np.array([0.5, 2.0, 1.0, 2.0 + 1e-12, 1.0 - 1e-12, np.nan, 3.0])
    assert ties.order(v).tolist() == [6, 1, 3, 2, 4, 0, 5]
    assert ties.order(v, descending=False).tolist() == [0, 2, 4, 1, 3, 6, 5]
    for seed in range(20):
        assert ties.order(_noisy(v, seed)).tolist() == [6, 1, 3, 2, 4, 0, 5]
    # what np.argsort does with the same noise: the order of the ties follows the bits
    exact = np.array([2.0, 1.0, 2.0, 1.0])
    flips = {tuple(np.argsort(-_noisy(exact, s), kind="stable")) for s in range(20)}
    assert len(flips) > 1
    assert {tuple(ties.order(_noisy(exact, s))) for s in range(20)} == {(0, 2, 1, 3)}
    assert ties.order([]).tolist() == [] and ties.order([4.0]).tolist() == [0]
    assert ties.order([1.0, 2.0], rtol=0.0, atol=5.0).tolist() == [0, 1]
    # per-value tolerances: a value summed from large terms carries their rounding
    assert ties.order([1.0, 1.0 + 1e-8, 1.0 + 2e-8], rtol=0.0,
                      atol=np.array([1e-12, 1e-7, 1e-12])).tolist() == [0, 1, 2]
    assert ties.order([1.0, 1.0 + 1e-8], rtol=0.0, atol=1e-12).tolist() == [1, 0]
    with pytest.raises(ValueError):
        ties.order(np.zeros((2, 2)))


def test_beats_needs_more_than_the_tolerance():
    assert ties.beats(1.0 + 1e-6, 1.0) and not ties.beats(1.0 + 1e-13, 1.0)
    assert not ties.beats(1.0, 1.0) and not ties.beats(np.nan, 0.0)
    assert ties.beats(1e12 + 10.0, 1e12) and not ties.beats(1e12 + 0.5, 1e12)   # relative


def test_products_without_blas_equal_the_blas_ones():
    rng = np.random.default_rng(1)
    M, v, B = rng.normal(size=(40, 13)), rng.normal(size=13), rng.normal(size=(13, 4))
    np.testing.assert_allclose(ties.matvec(M, v), M @ v, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ties.dot(v, v), v @ v, rtol=1e-12)
    np.testing.assert_allclose(ties.matmul(M, B), M @ B, rtol=1e-12, atol=1e-12)
    S = rng.normal(size=(5, 3, 3))
    np.testing.assert_allclose(ties.matmul(S, S), S @ S, rtol=1e-12, atol=1e-12)


_PROBE = """
import hashlib, json, numpy as np
from findme_core.geometry import ties
rng = np.random.default_rng(7)
M, v, B = rng.normal(size=(300, 13)), rng.normal(size=13), rng.normal(size=(13, 9))
F = rng.normal(size=(7, 40, 641))
h = lambda x: hashlib.sha1(np.ascontiguousarray(x).tobytes()).hexdigest()
print(json.dumps({"ties": [h(ties.matvec(M, v)), h(ties.matmul(M, B)),
                           h(ties.dot(v[:7, None, None], F, axis=0))],
                  "blas": [h(M @ v), h(M @ B), h(np.tensordot(v[:7], F, axes=1))]}))
"""

def test_products_without_blas_have_the_same_bits_under_every_kernel():
    """The point of ``ties.dot``: BLAS's own products differ between OpenBLAS kernels (shown
    here, so the test notices if that stops being so), ours do not. Every environment of
    ``tests/numeric_envs`` this CPU can run (SkylakeX needs AVX-512)."""
    envs = numeric_envs.runnable()
    assert len(envs) >= 3, envs   # Haswell, Sandybridge and numpy without AVX-512 at least
    runs = []
    for name, env in envs.items():
        r = numeric_envs.run_python(_PROBE, env)
        assert r.returncode == 0, f"{name}: {r.stderr[-2000:]}"
        runs.append(json.loads(r.stdout))
    assert all(r["ties"] == runs[0]["ties"] for r in runs)
    assert any(r["blas"] != runs[0]["blas"] for r in runs)


def _events(rows):
    a = np.array(rows, float).reshape(-1, 4)
    return Events(a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2].astype(int),
                  a[:, 2] - 0.5, a[:, 3].astype(bool))


def test_the_search_breaks_an_exact_tie_the_same_way_whatever_the_last_bits():
    """Two corners from track 0 onto tracks 1 and 2 at columns 4 and 6, then both on to
    track 3: tracks 1 and 2 are equally good (in exact arithmetic), so both paths score the
    same. Whatever the last bits of the rewards, the search takes the corner met first
    (column 4) and ranks the two paths in the order of their events."""
    W = 12
    gain = np.zeros((4, W))
    gain[0, :4], gain[0, 4:6], gain[3, 8:] = 0.3, 0.1, 0.3
    gain[1, 4:8], gain[2, 6:8] = 0.1, 0.1   # 0 -> 1 at 4 and 0 -> 2 at 6 gain 0.4 by 8
    A = np.zeros((4, W + 1))
    A[:, 1:] = np.cumsum(gain, axis=1)
    valid = np.ones((4, W), bool)
    ev = _events([(0, 1, 4, 0), (0, 2, 6, 0), (1, 3, 8, 0), (2, 3, 8, 0)])
    ref = best_paths(A, valid, ev, corner_cost=0.01, step_cost=1.0)
    assert ref[0][0] == pytest.approx(ref[1][0])
    for seed in range(30):
        got = best_paths(_noisy(A, seed), valid, ev, corner_cost=0.01, step_cost=1.0)
        assert [p[1:] for p in got] == [p[1:] for p in ref]
    assert [p[1:] for p in ref[:2]] == [(0, (0, 2)), (0, (1, 3))]   # column 4 first
