"""``tools/surface_coverage.py`` on a tiny dataset written here in the findme-eval layout: each
point is counted on the side of the surface the product put it on, against its query's kind."""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import surface_coverage as scov  # noqa: E402


def test_points_are_split_by_the_surface_they_were_put_on(tmp_path):
    (tmp_path / "views").mkdir()
    truth = {"floor_points": [{"px": [1, 9], "xyz_m": [0, 1, 2]}, {"px": [2, 9], "xyz_m": [0, 1, 3]}],
             "wall_points": [{"px": [1, 1], "xyz_m": [0, 0, 4]}] * 3}
    (tmp_path / "views" / "zt_r01_p1_v0.json").write_text(json.dumps({"id": "zt_r01_p1_v0", **truth}))
    (tmp_path / "index.json").write_text(json.dumps({"subsets": {"zind-tilted": {
        "views": ["zt_r01_p1_v0"]}}}))
    pred = {"floor_points": [[0, 1, 2.05], [0, 1, 3.5]], "floor_points_sigma_m": [0.1, 0.1],
            "floor_points_surface": ["floor", "wall"],
            # a wall point put on the floor 2 m off; one on the wall; one with no answer
            "wall_points": [[0, 0, 6], [0, 0, 4.1], None], "wall_points_sigma_m": [0.2, 0.2, None],
            "wall_points_surface": ["floor", "wall", None]}
    res = scov.collect(str(tmp_path), {"views": {"zt_r01_p1_v0": pred}})
    assert np.allclose(res["floor points (zind)"]["right"], [0.5])
    assert np.allclose(res["floor points (zind)"]["other"], [5.0])
    assert np.allclose(res["wall points (zind)"]["right"], [0.5])
    assert np.allclose(res["wall points (zind)"]["other"], [10.0])
    rows = scov.table(res, markdown=True)
    assert rows[2] == ("| floor points (zind) | 2 | 0.50 | 1.00 / 1.00 / 1.00 | 0.50 | "
                       "0.00 / 0.00 / 0.00 | 0.50 / 0.50 / 0.50 |")


def test_predictions_without_surfaces_say_so(tmp_path, capsys):
    (tmp_path / "views").mkdir()
    (tmp_path / "index.json").write_text(json.dumps({"subsets": {}}))
    preds = tmp_path / "p.json"
    preds.write_text(json.dumps({"views": {}}))
    assert scov.main([str(tmp_path), str(preds)]) == 1
    assert "_surface" in capsys.readouterr().err


def test_wall_points_are_split_by_whether_a_floor_point_of_their_view_got_a_note(tmp_path):
    (tmp_path / "views").mkdir()
    truth = {"floor_points": [{"px": [1, 9], "xyz_m": [0, 1, 2]}],
             "wall_points": [{"px": [1, 1], "xyz_m": [0, 0, 4]}] * 2}
    views = {"zt_r01_p1_v0": ["the chosen floor line runs below this point"], "zt_r02_p1_v0": [None],
             "zt_r03_p1_v0": None}                    # no note list: predicted without said surfaces
    for vid in views:
        (tmp_path / "views" / f"{vid}.json").write_text(json.dumps({"id": vid, **truth}))
    (tmp_path / "index.json").write_text(json.dumps({"subsets": {"zind-tilted": {"views": list(views)}}}))
    preds = {"views": {vid: {"floor_points": [[0, 1, 2]], "floor_points_sigma_m": [0.1],
                             "wall_points": [[0, 0, 4.1], [0, 0, 5 + i]], "wall_points_sigma_m": [0.2, 0.5],
                             **({} if n is None else {"floor_points_note": n})}
                       for i, (vid, n) in enumerate(views.items())}}
    res = scov.by_note(str(tmp_path), preds)
    assert np.allclose(res["wall points (zind)"]["noted"], [0.5, 2.0])
    assert np.allclose(res["wall points (zind)"]["not"], [0.5, 4.0])
    assert scov.note_table(res) == [
        "wall points (zind): views with a floor point noted n 2: 0.500 / 1.000 / 1.000; the other "
        "views n 2: 0.500 / 0.500 / 0.500 (within 1 / 2 / 3 sigma)"]
