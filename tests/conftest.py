"""Shared fixtures: synthetic rooms rendered once per test session (exact ground truth)."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest

from findme_core.synth.render import Box, Pose, Room, render

SHARED = Path(__file__).resolve().parents[2] / "shared"
EVAL_DIR = Path(os.environ.get("FINDME_EVAL_DIR", SHARED / "data" / "findme-eval"))
SCORER = Path(os.environ.get("FINDME_SCORER", SHARED / "eval" / "score.py"))

# The start of a script run in a fresh interpreter that must work without our code: any
# import of the project's packages or of Foxglove's generated classes fails there.
WITHOUT_PROJECT_CODE = textwrap.dedent("""
    import importlib.abc, json, sys

    BLOCKED = ("schemas", "findme_core", "findme", "services", "foxglove_schemas_protobuf",
               "foxglove")

    class Block(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"blocked in this test: {name}")
            return None

    sys.meta_path.insert(0, Block())
""")


def needs_eval_data():
    """Skip (with the reason) when the real evaluation set is not next to the checkout."""
    if not (EVAL_DIR / "index.json").exists():
        pytest.skip(f"real evaluation set not found at {EVAL_DIR} (set FINDME_EVAL_DIR); "
                    "it is not redistributed with the project")


@pytest.fixture(scope="session")
def room():
    return Room.rectangle(5.0, 6.0, floor_style="carpet")


@pytest.fixture(scope="session")
def level_view(room):
    """Level camera, 80 deg hfov, looking into a corner of a 5 x 6 m room."""
    return render(room, Pose(0.3, -1.5, 1.45, yaw_deg=25.0), 640, 480, hfov_deg=80.0, seed=1)


@pytest.fixture(scope="session")
def tilted_view(room):
    """Phone-like: pitched 30 deg down and rolled 4 deg."""
    return render(room, Pose(-0.4, -1.8, 1.4, yaw_deg=-20.0, pitch_deg=30.0, roll_deg=4.0),
                  640, 480, hfov_deg=70.0, seed=2)


@pytest.fixture(scope="session")
def box_view():
    """A cabinet stands on the floor in front of the far wall."""
    r = Room.rectangle(5.0, 6.0, floor_style="wood",
                       boxes=(Box(0.2, 1.2, 0.8, 0.5, 0.7, yaw_deg=15.0),))
    return render(r, Pose(0.0, -1.6, 1.3, yaw_deg=5.0, pitch_deg=25.0), 640, 480,
                  hfov_deg=70.0, seed=3)


@pytest.fixture(scope="session")
def side_view():
    """A cabinet turned 30 deg: the detector's step at its front corner leaves its side face
    on the floor's side of the line (as on TUM's cabinet, dev split; ``steps``)."""
    r = Room.rectangle(5.0, 6.0, floor_style="wood",
                       boxes=(Box(0.2, 1.2, 0.8, 0.5, 0.7, yaw_deg=30.0),))
    return render(r, Pose(0.0, -1.6, 1.3, yaw_deg=5.0, pitch_deg=25.0), 640, 480,
                  hfov_deg=70.0, seed=3)


def side_face_pixels(view, box: int = 0, step: int = 1):
    """(N, 2) pixels (every ``step``-th, raster order) of ``view``'s box in its few leftmost
    columns (its side face, turned away), below its top and below the foot of the wall seen
    just left of it (the side face a step at the box's front corner leaves on the floor's
    side), and their (N, 3) true camera-frame points."""
    import numpy as np
    b = view.room.boxes[box]
    level = view.points_cam.reshape(-1, 3) @ view.camera.R_level_from_cam.T
    height = view.camera_height - level[:, 1]
    W = view.labels.shape[1]
    on = (view.labels.ravel() == 50 + box) & (height < b.height - 0.02)
    left = int(np.percentile(np.flatnonzero(on) % W, 1))
    wall = np.flatnonzero((view.labels[:, left - 8] > 0) & (view.labels[:, left - 8] < 50))
    rows, cols = np.arange(on.size) // W, np.arange(on.size) % W
    pick = np.flatnonzero(on & (cols <= left + 6) & (rows > wall.max() + 4))[::step]
    return (np.column_stack([pick % W, pick // W]).astype(float),
            view.points_cam.reshape(-1, 3)[pick])


@pytest.fixture(scope="session")
def counter_view():
    """A counter 0.9 m high, 3 m long and 0.7 m deep against the far wall: the boundary runs
    along its foot, and the photo looks down on its top."""
    r = Room.rectangle(5.0, 6.0, floor_style="wood", boxes=(Box(0.0, 2.65, 3.0, 0.7, 0.9),))
    return render(r, Pose(0.2, 0.0, 1.45, yaw_deg=3.0, pitch_deg=28.0, roll_deg=2.0), 640, 480,
                  hfov_deg=70.0, seed=8)


def top_pixels(view, box: int = 0, step: int = 97):
    """(N, 2) pixels (every ``step``-th, in raster order) of the top of ``view``'s box, and
    their (N, 3) true camera-frame points."""
    import numpy as np
    level = view.points_cam.reshape(-1, 3) @ view.camera.R_level_from_cam.T
    height = view.camera_height - level[:, 1]
    on = np.flatnonzero((view.labels.ravel() == 50 + box)
                        & (np.abs(height - view.room.boxes[box].height) < 1e-3))[::step]
    W = view.labels.shape[1]
    return np.column_stack([on % W, on // W]).astype(float), view.points_cam.reshape(-1, 3)[on]


@pytest.fixture(scope="session")
def l_view():
    """A non-convex (L-shaped) room: one wall corner occludes another wall."""
    return render(Room.l_shape(), Pose(-1.5, -1.5, 1.5, yaw_deg=30.0, pitch_deg=20.0), 640, 480,
                  hfov_deg=70.0, seed=4)


def floor_pixel_error(polyline, labels):
    """Fraction of pixels whose floor / not-floor label the polyline gets wrong (as the
    evaluation's scorer: floor = pixel centres at or below the polyline)."""
    import numpy as np
    H, W = labels.shape
    vp = np.interp(np.arange(W, dtype=float), polyline[:, 0], polyline[:, 1])
    pred = np.arange(H, dtype=float)[:, None] >= vp[None, :] - 1e-6
    valid = labels != 255
    return float(((pred != (labels == 0)) & valid).sum() / valid.sum())


def png_bomb(idat_length: int = 0xFFFFFFFF, pad: int = 400_000) -> bytes:
    """A 640x480 RGB PNG whose IDAT chunk CLAIMS ``idat_length`` bytes while the file holds
    only ~``pad`` (issue 11: a 404 kB file with 0xFFFFFFFF made the decoder allocate ~4 GB).
    The header is valid, so checking the declared width x height does not catch it."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    raw = zlib.compress(b"".join(b"\x00" + bytes(640 * 3) for _ in range(480)))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 640, 480, 8, 2, 0, 0, 0))
            + struct.pack(">I", idat_length) + b"IDAT" + raw + bytes(pad))


def memory_cap(nbytes: int):
    """A ``preexec_fn`` capping a child's data segment (RLIMIT_DATA): a test that feeds a
    process something an unbounded decoder would allocate gigabytes for cannot take the
    shared machine's memory; the test asserts a peak far below the cap."""
    def limit():
        import resource
        resource.setrlimit(resource.RLIMIT_DATA, (nbytes, nbytes))
    return limit


def peak_rss_bytes(pid: int) -> int:
    """A live process's peak resident memory (VmHWM, Linux)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    raise AssertionError(f"no VmHWM for process {pid}")
