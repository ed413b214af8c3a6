"""The one exception root of Find Me and a subclass per area.

Every message names the offending value, so a user reading one line on stderr (or on a
session's ``error`` key) knows what to change.
"""

from __future__ import annotations


class FindmeError(Exception):
    """Root of every error Find Me raises on purpose."""


class InputError(FindmeError):
    """A user-supplied value is malformed (flags, files, JSON, image bytes)."""


class ImageError(InputError):
    """An image is unreadable, corrupt, not an image, or over the size limit."""


class CameraError(FindmeError):
    """Intrinsics or gravity are invalid or degenerate."""


class GeometryError(FindmeError):
    """A geometric query has no answer (pixel above the horizon, ray parallel to a wall,
    point behind the camera, degenerate configuration)."""


class HypothesisError(FindmeError):
    """A hypothesis does not exist or cannot be built."""


class MotionError(FindmeError):
    """Planar motion cannot be estimated (too few matches, no common view, identical photos)."""


class SchemaError(FindmeError):
    """A bus message is malformed or of the wrong type."""


class BusError(FindmeError):
    """A Zenoh bus operation failed (unknown session, oversized message, no service)."""


class RecordingError(FindmeError):
    """An MCAP recording is unreadable or cannot be written."""


class OutlineRefused(GeometryError):
    """A floor plan's outline contradicts its own photos (they saw past one of its walls), so
    it must not be shown; where the photos were taken stands, each with its own 1-sigma.

    Attributes:
        plan: the ``floorplan.Plan`` whose outline was refused (its poses and their sigmas
            are the photos' places; its polygon and walls must not be shown).
        placement: the ``fuse.Placement`` behind it (spots, blocks, alternatives).
        timing_ms: stage -> milliseconds, as ``session.plan`` gives them.
    """

    def __init__(self, reason: str, plan=None, placement=None, timing_ms=None):
        super().__init__(reason)
        self.plan, self.placement, self.timing_ms = plan, placement, dict(timing_ms or {})
