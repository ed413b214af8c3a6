"""Per-type structural checks of bus messages (no geometry, no findme_core).

A check returns the list of problems of one message; each problem names the field and the
offending value. What is checked is what a consumer could not do without: the session id
is usable in a key, required parts are present, numbers are finite and in range, enum
values are known, repeated fields agree in length, and a failure carries no numbers.
Geometry (is the camera sane, does the boundary span the image) is left to the services.

The checks live beside the messages they check (``_photo``, ``_motion``, ``_plan``; the
status messages' here), the fields and limits they share in ``_fields``; ``VALIDATORS``
maps each message type to its check.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ._fields import Problems, _enum, _session
from ._motion import _motion, _pose, _trajectory
from ._photo import (_frame, _hypothesis_set, _measure_reply, _measure_request, _scene,
                     _selection)
from ._plan import _plan
from .v1 import (frame_pb2, hypotheses_pb2, measure_pb2, motion_pb2, plan_pb2, scene_pb2,
                 selection_pb2, status_pb2)


def _error(m: status_pb2.Error) -> Problems:
    p: Problems = []
    _session(p, m.session, allow_empty=True)
    _enum(p, "code", status_pb2.ErrorCode, m.code, allow_zero=False)
    if not m.message.strip():
        p.append("message is empty: say what went wrong")
    return p


def _service_status(m: status_pb2.ServiceStatus) -> Problems:
    p: Problems = []
    if not m.service:
        p.append("service is empty")
    if not m.instance:
        p.append("instance is empty")
    return p


VALIDATORS: dict[str, Callable[[Any], Problems]] = {
    cls.DESCRIPTOR.full_name: fn for cls, fn in [
        (frame_pb2.Frame, _frame),
        (hypotheses_pb2.HypothesisSet, _hypothesis_set),
        (selection_pb2.Selection, _selection),
        (scene_pb2.Scene, _scene),
        (measure_pb2.MeasureRequest, _measure_request),
        (measure_pb2.MeasureReply, _measure_reply),
        (motion_pb2.Motion, _motion),
        (motion_pb2.Pose, _pose),
        (motion_pb2.Trajectory, _trajectory),
        (plan_pb2.Plan, _plan),
        (status_pb2.Error, _error),
        (status_pb2.ServiceStatus, _service_status),
    ]
}
