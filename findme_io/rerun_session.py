"""A Rerun session: ``SessionView`` routes one session's bus messages to the ``log_*``
adapters of ``rerun_views`` (keeping what they need from earlier messages), and
``blueprint`` lays the session out. Frames and timelines: see ``rerun_views``."""

from __future__ import annotations

from .rerun_plan import log_plan
from .rerun_views import (_rr, _set_time, camera_of, log_boundary, log_error, log_frame,
                          log_hypotheses, log_measure, log_motion, log_pose, log_sources,
                          log_trajectory, photo_path)


def blueprint(photos, plan: bool = False):
    """Photos in tabs on the left (each with its hypotheses, chosen boundary and taps), the
    room in 3D (session frame), the floor plan top-down (once there is one) and the log on
    the right."""
    import rerun.blueprint as rrb
    photos = sorted(set(photos)) or [0]
    tabs = [rrb.Spatial2DView(name=f"photo {n}", origin=f"{photo_path(n)}/camera/image")
            for n in photos]
    right = [rrb.Spatial3DView(name="room (level frame of photo 0: x right, y down, z forward)",
                               origin="world")]
    if plan:
        right.append(rrb.Spatial2DView(name="floor plan (top-down: x right, forward up; m)",
                                       origin="plan"))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(*tabs, active_tab=len(tabs) - 1),
            rrb.Vertical(*right, rrb.TextLogView(name="log", origin="log"),
                         row_shares=[4] * len(right) + [1]),
            column_shares=[3, 2]),
        collapse_panels=True)


#: photos with their own tab in the blueprint: the first ones, as their number reaches 1, 2,
#: 4 or 8 (a 3rd photo gets its tab with the 4th); all are in the 3D view and the entity
#: tree. Rerun makes a stream for every layout sent and never frees it (rerun#2116: 0.6 MB
#: each, measured), so a session sends at most 5 (``layouts`` counts them).
MAX_PHOTO_TABS = 8


class SessionView:
    """Routes one session's bus messages to the adapters, keeping what they need from
    earlier messages (each photo's camera, how many measurements a photo has)."""

    def __init__(self, rec):
        self.rec = rec
        self.photos: set[int] = set()
        self.cameras: dict[int, object] = {}
        self.measures: dict[int, int] = {}
        self.has_plan = False
        self.logged = 0
        self.layouts = 0   # layouts sent (each a stream Rerun keeps)
        self.indices: set[int] = set()   # photo numbers drawn (their entities stay in Rerun)
        self._blueprint_for: tuple = ()
        rr = _rr()
        rec.log("world", rr.ViewCoordinates.RDF, static=True)

    def update_blueprint(self) -> None:
        shown = sorted(self.photos)[:MAX_PHOTO_TABS]
        tabs = 1 << (len(shown).bit_length() - 1) if shown else 0   # 1, 2, 4 or 8
        key = (tuple(shown[:tabs]), self.has_plan)
        if key != self._blueprint_for:
            self._blueprint_for = key
            self.layouts += 1
            self.rec.send_blueprint(blueprint(*key))

    def log(self, msg, t_ns: int | None = None) -> bool:
        """Show one message; False when it is of a type this view does not draw."""
        name = msg.DESCRIPTOR.full_name.rsplit(".", 1)[1]
        rec = self.rec
        for field in ("index", "index_b"):   # a photo's entities (Rerun keeps them)
            if msg.DESCRIPTOR.fields_by_name.get(field) is not None:
                self.indices.add(getattr(msg, field))
        if name == "Frame":
            n = msg.index
            _set_time(rec, n, t_ns or msg.capture_time_ns)
            if n == 0:
                rec.log(photo_path(0), _rr().Transform3D(translation=[0.0, 0.0, 0.0]))
            cam = camera_of(msg)
            self.cameras[n] = cam
            log_frame(rec, photo_path(n), msg, cam)
            self.photos.add(n)
            self.update_blueprint()
        elif name == "HypothesisSet":
            _set_time(rec, msg.index, t_ns)
            log_hypotheses(rec, f"{photo_path(msg.index)}/camera/image", msg)
            if msg.HasField("camera"):
                log_sources(rec, photo_path(msg.index), msg.index, msg.camera)
        elif name == "Scene":
            _set_time(rec, msg.index, t_ns)
            log_boundary(rec, photo_path(msg.index), msg)
        elif name == "MeasureReply":
            _set_time(rec, msg.index, t_ns)
            k = self.measures.get(msg.index, 0)
            self.measures[msg.index] = k + 1
            log_measure(rec, photo_path(msg.index), msg, k)
        elif name == "Pose":
            _set_time(rec, msg.index, t_ns)
            log_pose(rec, photo_path(msg.index), msg)
        elif name == "Trajectory":
            _set_time(rec, max((p.index for p in msg.poses), default=0), t_ns)
            log_trajectory(rec, "world/trajectory", msg)
        elif name == "Motion":
            _set_time(rec, msg.index_b, t_ns)
            log_motion(rec, "log", msg)
        elif name == "Plan":
            _set_time(rec, msg.up_to_index, t_ns)
            log_plan(rec, "plan", msg)
            self.has_plan = True
            self.update_blueprint()
        elif name == "Error":
            _set_time(rec, None, t_ns)
            log_error(rec, "log", msg)
        else:
            return False
        self.logged += 1
        return True

