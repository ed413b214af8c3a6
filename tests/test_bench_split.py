"""bench_load's split of the CPU per photo posed (``load_rig.posed_split``): the handlers on
the way to a pose, those processes' intake, and the services that take in every photo."""

import pytest

from bench.load_rig import posed_split


def _row(tag, cpu, handle=None, tick=0.0):
    r = {"process": tag, "cpu_ms": cpu}
    if handle is not None:
        r.update(handle_cpu_ms=handle, tick_cpu_ms=tick, other_cpu_ms=cpu - handle - tick)
    return r


def test_cpu_per_photo_posed_splits_into_path_intake_and_the_rest():
    # 400 photos offered, 100 posed: every per-offered figure counts 4 times per posed
    run = {"offered": 400, "delivered": 100, "breakdown": [
        _row("h0", 8.0, 7.0), _row("h1", 8.0, 7.0), _row("o0", 11.0, 10.0, 0.5),
        _row("selection", 0.5, 0.2), _row("measurement", 1.0, 0.7),
        _row("store", 1.5, 0.0), _row("recorder", 3.0, 1.5), _row("mapper", 2.5, 2.0),
        _row("router", 1.2), _row("ALL", 36.7)]}
    s = posed_split(run)
    assert s["offered_per_posed"] == 4.0
    assert s["path"] == pytest.approx(4 * (7 + 7 + 10.5 + 0.2 + 0.7))
    assert s["intake"] == pytest.approx(4 * (1 + 1 + 0.5 + 0.3 + 0.3))
    assert s["off_path"] == pytest.approx(4 * (1.5 + 3.0 + 2.5 + 1.2))
    assert s["all"] == pytest.approx(4 * 36.7)
