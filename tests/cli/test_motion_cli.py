"""``findme motion`` (JSON contract, text, bad input) and the pairs of ``findme eval``, on a
rendered pair with known motion, through the real entry point."""

from __future__ import annotations

import json

import cv2
import pytest

from findme_core.synth.render import Box, Pose, Room, planar_motion, render
from tests.cli.conftest import as_json, intrinsics_flag, run_findme

POSES = (Pose(0.2, -1.6, 1.45, -5.0, 22.0, 2.0), Pose(0.6, -1.0, 1.45, 12.0, 25.0, -2.0))


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    room = Room.rectangle(5.0, 6.0, floor_style="carpet", boxes=(Box(1.0, 1.6, 0.8, 0.5, 0.9, 20),))
    d = tmp_path_factory.mktemp("pair")
    views = [render(room, p, 640, 480, hfov_deg=70.0, seed=3, supersample=1) for p in POSES]
    paths = []
    for name, v in zip("ab", views):
        paths.append(d / f"{name}.png")
        cv2.imwrite(str(paths[-1]), v.image)
    return views, paths


def _flags(views):
    g = lambda v: ",".join(f"{x:.9f}" for x in v.camera.gravity)  # noqa: E731
    return ["--intrinsics", intrinsics_flag(views[0].camera), f"--gravity-a={g(views[0])}",
            f"--gravity-b={g(views[1])}"]


def test_json_contract_and_accuracy(pair):
    views, (a, b) = pair
    out = as_json(run_findme("motion", a, b, *_flags(views), "--camera-height", 1.45, "--json"))
    assert set(out) >= {"x_m", "z_m", "yaw_deg", "inliers", "matches", "timing_ms", "sigma_x_m",
                        "sigma_z_m", "sigma_yaw_deg", "metric", "method", "scale_points"}
    assert out["metric"] is True and out["method"] == "findme"
    assert isinstance(out["inliers"], int) and 0 < out["inliers"] <= out["matches"]
    assert set(out["timing_ms"]) >= {"features", "matching", "motion", "hypotheses"}
    x, z, yaw = planar_motion(*POSES)
    assert abs(out["x_m"] - x) < 0.05 and abs(out["z_m"] - z) < 0.05
    assert abs(out["yaw_deg"] - yaw) < 0.5
    assert 0 < out["sigma_x_m"] < 0.2 and 0 < out["sigma_yaw_deg"] < 2
    # the evidence: the two photos' layouts registered (rank-1 walls), and the candidates
    lay = out["layout"]
    assert lay["hypotheses"] == [1, 1] and lay["samples"] > 20 and lay["walls"]
    assert all(len(w) == 2 for w in lay["walls"]) and lay["rms_m"] < 0.1
    assert isinstance(out["alternatives"], list)
    for alt in out["alternatives"]:
        assert set(alt) >= {"x_m", "z_m", "yaw_deg", "sigma_x_m", "inliers", "score"}
        assert alt["score"] <= out["score"]


def test_feature_only_method_is_selectable(pair):
    views, (a, b) = pair
    out = as_json(run_findme("motion", a, b, *_flags(views), "--camera-height", 1.45, "--json",
                             "--method", "features"))
    assert out["method"] == "features" and "layout" not in out and out["alternatives"] == []
    x, z, yaw = planar_motion(*POSES)
    assert abs(out["x_m"] - x) < 0.1 and abs(out["yaw_deg"] - yaw) < 1.0


def test_paper_method_text_output_and_up_to_scale(pair):
    views, (a, b) = pair
    p = run_findme("motion", a, b, *_flags(views), "--method", "paper")
    assert p.returncode == 0 and "photo B relative to photo A (paper)" in p.stdout
    assert "camera heights" in p.stdout and "up to scale" not in p.stdout
    assert "units of the camera height" in p.stderr


@pytest.mark.parametrize("args, message", [
    (["missing.png", "{b}"], "no such file"),
    (["{a}", "{b}", "--gravity-a", "0,1"], "--gravity-a needs 3"),
    (["{a}", "{b}", "--hypothesis-b", "0"], "hypothesis 0 of photo B does not exist"),
    (["{a}", "{a}"], "identical"),
    (["{a}", "{b}", "--method", "surf"], "invalid choice"),
    (["{a}", "{b}", "--camera-height", "-1"], "--camera-height"),
    (["{a}", "{b}", "--hfov", "200"], "field of view"),
])
def test_bad_input_is_one_line_and_exit_2(pair, args, message):
    _, (a, b) = pair
    p = run_findme("motion", *[s.format(a=a, b=b) for s in args], check=False)
    assert p.returncode == 2, p.stderr
    assert message in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


def _dataset(tmp_path, views):
    """A findme-eval layout with the two views and one pair (inputs + ground truth)."""
    (tmp_path / "views").mkdir(parents=True)
    (tmp_path / "pairs").mkdir()
    ids = []
    for name, v in zip("ab", views):
        vid = f"syn_{name}"
        cv2.imwrite(str(tmp_path / "views" / f"{vid}.png"), v.image)
        c = v.camera
        (tmp_path / "views" / f"{vid}.json").write_text(json.dumps({
            "id": vid, "image": f"{vid}.png", "camera_height_m": v.camera_height,
            "gravity_cam": c.gravity.tolist(),
            "intrinsics": {"fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
                           "width": c.width, "height": c.height}}))
        ids.append(vid)
    x, z, yaw = planar_motion(*POSES)
    (tmp_path / "pairs" / "syn_pair.json").write_text(json.dumps(
        {"id": "syn_pair", "a": ids[0], "b": ids[1],
         "motion": {"x_m": x, "z_m": z, "yaw_deg": yaw}}))
    (tmp_path / "index.json").write_text(json.dumps({"subsets": {
        "syn-pairs": {"type": "pairs", "views": ids, "pairs": ["syn_pair"]}}}))
    return tmp_path


def test_eval_writes_pair_predictions_for_each_motion_method(pair, tmp_path):
    views, _ = pair
    ds = _dataset(tmp_path / "ds", views)
    out = tmp_path / "pred.json"
    p = run_findme("eval", ds, "--out", out, "--motion-method", "findme,paper", "--jobs", 1)
    assert "1 of 1 pairs (findme)" in p.stdout
    pred = json.loads(out.read_text())
    assert set(pred["views"]) == {"syn_a", "syn_b"} and pred["motion_method"] == "findme"
    x, z, yaw = planar_motion(*POSES)
    m = pred["pairs"]["syn_pair"]
    assert abs(m["x_m"] - x) < 0.05 and abs(m["z_m"] - z) < 0.05 and abs(m["yaw_deg"] - yaw) < 0.5
    paper = json.loads((tmp_path / "pred.paper.json").read_text())
    assert paper["motion_method"] == "paper" and set(paper["views"]) == {"syn_a", "syn_b"}
    assert set(paper["pairs"]) <= {"syn_pair"}


def test_eval_rejects_an_unknown_motion_method(pair, tmp_path):
    views, _ = pair
    ds = _dataset(tmp_path / "ds", views)
    p = run_findme("eval", ds, "--out", tmp_path / "p.json", "--motion-method", "findme,surf",
                   check=False)
    assert p.returncode == 2 and "--motion-method" in p.stderr and "Traceback" not in p.stderr
