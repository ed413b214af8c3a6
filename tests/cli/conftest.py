import json
import subprocess
import sys

import cv2
import pytest


def run_findme(*args, check=True, timeout=120):
    """Run the real ``findme`` entry point in a subprocess; returns CompletedProcess."""
    p = subprocess.run([sys.executable, "-m", "findme.cli", *map(str, args)],
                       capture_output=True, text=True, timeout=timeout)
    if check and p.returncode != 0:
        raise AssertionError(f"findme {args} exited {p.returncode}: {p.stderr}")
    return p


@pytest.fixture(scope="session")
def level_jpg(tmp_path_factory, level_view):
    path = tmp_path_factory.mktemp("img") / "level.jpg"
    cv2.imwrite(str(path), level_view.image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    return path


def intrinsics_flag(cam):
    return f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}"


def as_json(p):
    return json.loads(p.stdout)
