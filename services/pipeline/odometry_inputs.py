"""What one photo's motions need, from its messages: the image at the working size, its
camera, its hypotheses, the selected rank, the camera height and the hypotheses' lines.
Pure of the bus: ``odometry.OdometryHandler`` fetches the messages."""

from __future__ import annotations

from dataclasses import replace

import schemas
from findme_core.errors import HypothesisError
from findme_core.single.segments import WORK_SIZE
from findme_io.convert import msg_camera, msg_hypotheses, msg_lines
from findme_io.frame_photo import frame_camera, scaled_camera, scaled_polyline
from findme_io.imageio import decode_photo


def photo_inputs(frame: schemas.Frame, hset: schemas.HypothesisSet, sel: schemas.Selection,
                 n: int):
    """(image (H, W, 3) uint8, camera, hypotheses, selected rank, camera height in metres
    (1.0: lengths in camera heights), lines (K, 4) pixels or None) of photo n, at the
    working size: a large photo is decoded once at a JPEG reduction (``imageio.reduction``;
    a 12 MP photo at a quarter) and its camera, hypotheses and lines are scaled to match
    (pixel centres kept); the motion is in metres either way. The camera is the one the
    hypotheses were built with (its gravity possibly estimated), else the frame's.

    Raises:
        HypothesisError: the selected rank is not one of the hypotheses'.
        FindmeError: the frame's image does not decode.
    """
    photo = decode_photo(frame.image.data, f"frame {n}", reduce_to=WORK_SIZE)
    image, s = photo.image, photo.scale
    cam = (msg_camera(hset.camera) if hset.HasField("camera")
           else frame_camera(frame, photo.width, photo.height))
    h = (sel.camera_height_m if sel.HasField("camera_height_m") else
         frame.camera_height_m if frame.HasField("camera_height_m") else 1.0)
    hyps = msg_hypotheses(hset)
    if not 1 <= sel.rank <= len(hyps):
        raise HypothesisError(f"selection of hypothesis {sel.rank} of photo {n}, which has "
                              f"{len(hyps)} hypotheses")
    lines = msg_lines(hset)
    if s != 1.0:
        cam = scaled_camera(cam, s, image.shape[1], image.shape[0])
        hyps = [replace(hy, polyline=scaled_polyline(hy.polyline, s, image.shape[1]))
                for hy in hyps]
        lines = None if lines is None else (lines + 0.5) * s - 0.5
    return image, cam, hyps, sel.rank, h, lines
