"""``tools/choose_snap.py``'s choice: the tolerance with the most walls ok plus views
localised over the rooms and both gravities, the smaller one of a tie, and each room left out
of its own choice."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import choose_snap as cs  # noqa: E402


def _cells(ok_loc):
    """One room's per-candidate cells from [(walls ok, localised), ...]."""
    return [{"ok": o, "loc": q} for o, q in ok_loc]


def test_choose_takes_the_best_total_and_the_smaller_of_a_tie():
    n = len(cs.CANDIDATES)
    flat = [(0.5, 0.5)] * n
    better_at_2 = [(0.5, 0.5)] * 2 + [(1.0, 1.0)] * (n - 2)   # best from the third on
    res = {}
    for g in cs.GRAVITIES:
        res["a", g], res["b", g] = _cells(flat), _cells(better_at_2)
    assert cs.choose(res, ["a"]) == 0           # all tie: the smallest tolerance
    assert cs.choose(res, ["a", "b"]) == 2      # the first of the best
    assert cs.choose(res, ["b"]) == 2


def test_a_room_left_out_does_not_decide_its_own_tolerance():
    n = len(cs.CANDIDATES)
    res = {}
    for g in cs.GRAVITIES:
        res["a", g] = _cells([(0.0, 0.0)] * (n - 1) + [(1.0, 1.0)])   # only the last helps a
        res["b", g] = _cells([(1.0, 1.0)] + [(0.9, 0.9)] * (n - 1))   # b prefers the first
    assert cs.choose(res, ["a", "b"]) == n - 1
    assert cs.choose(res, ["b"]) == 0           # a's fold: chosen on b alone
