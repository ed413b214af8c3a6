"""``tools/weak_support.py`` on pairs written here in the findme-eval layout: the term it tries
(c * |t| added to the translation sigma of pairs with fewer than N agreeing matches) is fitted
where the weakly supported pairs are off by more than their sigma says, and not where they are
not; leaving a room out refits without that room's pairs."""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import weak_support as ws  # noqa: E402


def _run(tmp_path: Path, weak_error_m: float) -> Path:
    """Two rooms of 12 pairs, 1 m baselines, sigmas 0.05 m: half supported by 200 matches and
    off by 0.03 m, half by 6 and off by ``weak_error_m``."""
    (tmp_path / "pairs").mkdir()
    preds, ids = {}, []
    for room in (1, 2):
        for i in range(12):
            pid = f"zpt_r{room:02d}_p{i}_p{i + 1}_t0"
            ids.append(pid)
            (tmp_path / "pairs" / f"{pid}.json").write_text(json.dumps(
                {"motion": {"x_m": 0.0, "z_m": 1.0, "yaw_deg": 0.0}}))
            weak = i % 2 == 1
            err = weak_error_m if weak else 0.03 * (1 if i % 4 else -1)
            preds[pid] = {"x_m": 0.0, "z_m": 1.0 + err, "yaw_deg": 0.0, "sigma_x_m": 0.05,
                          "sigma_z_m": 0.05, "inliers": 6 if weak else 200}
    (tmp_path / "index.json").write_text(json.dumps(
        {"subsets": {"zind-pairs-tilted": {"pairs": ids}}}))
    out = tmp_path / "pred.json"
    out.write_text(json.dumps({"pairs": preds}))
    return out


def test_the_term_is_fitted_where_weak_pairs_are_off_and_not_where_they_are_not(tmp_path):
    off = ws.pairs(str(tmp_path), str(_run(tmp_path, 0.4)))
    n_max, c = ws.fit(off)
    assert c > 0 and 6 < n_max <= 200                     # only the weak pairs widen
    z = ws.z_scores(off, n_max, c)
    assert (z[:, 1] <= 3).mean() > (ws.z_scores(off, n_max, 0.0)[:, 1] <= 3).mean()
    assert ws.fit([r for r in off if r["group"] != "room01"]) == (n_max, c)   # same rooms alike

    fine = tmp_path / "fine"
    fine.mkdir()
    assert ws.fit(ws.pairs(str(fine), str(_run(fine, 0.03)))) == (ws.N_GRID[0], 0.0)
