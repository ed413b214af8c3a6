"""bench/bench_pipeline.py drives the real handlers as the bus would: a rendered pair goes
through every stage to a pose (the timings themselves are a benchmark, not a test). The
compute bound of ``bench_load`` is this same drive, so a handler whose inputs change
must still be fed what it subscribes to here."""

from bench import bench_pipeline


def test_a_rendered_pair_goes_through_every_stage_to_a_pose(tmp_path, monkeypatch):
    monkeypatch.setattr(bench_pipeline, "EVAL_DIR", tmp_path / "no-data")   # rendered pairs
    _, photos = next(bench_pipeline.pairs())
    per, poses = bench_pipeline.run_session("bench-smoke", photos, tmp_path)
    assert poses == 2          # a pose per photo: the first is the origin
    assert len(per) == 2 and all(set(bench_pipeline.STAGES) <= set(p) for p in per)
    assert all(p[s] > 0 for p in per for s in ("hypotheses", "measurement", "odometry"))
    assert (tmp_path / "bench-smoke.mcap").stat().st_size > 0
