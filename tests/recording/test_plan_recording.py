"""The floor plan end to end on the bus (embedded Group, one in-process Zenoh session): a
rendered room's photos, hypotheses and selections go out, the mapper publishes the plan as
they arrive, the recorder records it (decoded by a reader with none of our code, with its
Foxglove view) and the viewer service shows it in Rerun (read back from the .rrd)."""

from __future__ import annotations

import threading

import pytest

import schemas
from findme_core.synth.room import Room
from services.pipeline.mapper import MapperHandler
from services.recording.recorder import RecorderHandler
from services.recording.viewer import Sink, ViewerHandler
from services.runtime import bus
from services.runtime.service import Group
from tests.plan_room import rendered_session

from .test_generic_reader import _read_generically
from .test_rrd import column, rrd_contents

SID = "plan-e2e"


class Plans:
    """The plans arriving on findme/<SID>/plan; wait for one that took in every photo."""

    def __init__(self, session):
        self.cv, self.items = threading.Condition(), []
        self.sub = session.declare_subscriber(bus.key(SID, "plan"), self._cb)

    def _cb(self, sample):
        with self.cv:
            self.items.append(schemas.decode(schemas.Plan, sample.payload.to_bytes()))
            self.cv.notify_all()

    def wait_final(self, n: int, timeout: float = 120.0):
        def final():
            return any(p.photos == n and not p.reason for p in self.items)
        with self.cv:
            assert self.cv.wait_for(final, timeout), [(p.photos, p.reason) for p in self.items]
            return list(self.items)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """One spot turning round a 4.5 x 3.5 m room: 6 photos through the bus."""
    tmp = tmp_path_factory.mktemp("plan-e2e")
    room = rendered_session(Room.rectangle(4.5, 3.5), [(0.3, -0.2)], yaws=range(0, 360, 60),
                            session=SID)
    session = bus.open_session(bus.BusConfig())
    group = Group(session)
    try:
        recorder = group.add(RecorderHandler(tmp)).handler
        viewer = group.add(ViewerHandler(Sink("rrd", path=str(tmp)))).handler
        group.add(MapperHandler())
        plans = Plans(session)
        sent = 0
        for key, msg in room.messages():
            bus.put(session, key, schemas.encode(msg))
            sent += 1
        got = plans.wait_final(len(room.frames))
        assert recorder.wait_recorded(sent + len(got)), recorder.counters()
        assert viewer.wait_handled(sent + len(got)), viewer.counters()
        plans.sub.undeclare()
    finally:
        group.stop()           # the recorder and viewer finish their files
        session.close()
    return room, got, recorder.path_of(SID), tmp / f"{SID}.rrd", viewer


def test_the_plan_on_the_bus_is_the_room(recorded):
    room, plans, _, _, _ = recorded
    last = plans[-1]
    assert last.closed and last.photos == 6 and last.origin_index == 0
    assert sorted(w.length_m for w in last.walls) == pytest.approx(room.wall_lengths(), abs=0.03)
    assert [p.up_to_index for p in plans] == sorted(p.up_to_index for p in plans)


def test_the_plan_is_recorded_and_decodes_without_our_code(recorded, tmp_path):
    room, plans, mcap, _, _ = recorded
    res = _read_generically(mcap, tmp_path)
    assert res["leaked"] == []
    chans = res["channels"]
    assert chans[f"findme/{SID}/plan"]["type"] == "findme.v1.Plan"
    assert chans[f"findme/{SID}/plan"]["n"] == len(plans)
    first = res["first"][f"findme/{SID}/plan"]
    assert first["session"] == SID and "poses" in first
    view = chans[f"findme/{SID}/foxglove/plan"]
    assert view["type"] == "foxglove.SceneUpdate" and view["n"] == len(plans)
    # the last plan's view: walls as lines, their lengths as text, a numbered arrow per photo
    from services.recording.mcap_reader import read_recording
    (scene,) = [r for r in read_recording(mcap, views=True)
                if r.topic == f"findme/{SID}/foxglove/plan"][-1:]
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
    up = SceneUpdate.FromString(scene.payload)
    (e,) = up.entities
    assert e.frame_id == f"{SID}/level/0" and e.id == "plan"
    assert sum(len(line.points) for line in e.lines) == 2 * len(plans[-1].walls)
    labels = [t.text for t in e.texts]
    assert sum(t.endswith(" m ± 0.02") or " m ± " in t for t in labels) >= 4
    assert len(e.arrows) == 6
    for w, t in zip(plans[-1].walls, labels):
        assert t.startswith(f"{w.length_m:.2f} m")


def test_the_plan_is_in_rerun(recorded):
    room, plans, _, rrd, viewer = recorded
    assert viewer.counters()["not_shown"] == 0
    c = rrd_contents(rrd)
    assert {"LineStrips2D:strips", "LineStrips2D:labels"} <= c["/plan/walls"]
    assert {"Arrows2D:origins", "Arrows2D:vectors"} <= c["/plan/cameras"]
    assert "LineStrips3D:strips" in c["/world/photo/0/plan/walls"]
    labels = column(rrd, "/plan/walls", "LineStrips2D:labels")[-1]
    lengths = sorted(float(t.split()[0]) for t in labels)
    assert lengths == pytest.approx(room.wall_lengths(), abs=0.03)
    cams = column(rrd, "/plan/cameras", "Arrows2D:labels")[-1]
    assert cams == [str(i) for i in range(1, 7)]
    import rerun.chunk as rcc
    assert rcc.RrdReader(str(rrd)).blueprints()
