"""Decode speed: our decoder (Pillow, bounded, EXIF, upright BGR) against cv2.imdecode, one core.

    python bench/bench_decode.py [--repeat 15]

JPEG photos 640x480 and 12 MP (4000x3000), quality 90, made from a dev view (or a rendered
room without the data), decoded alternately by ``findme_io.imageio.decode_image`` and by
``cv2.imdecode(IMREAD_COLOR)`` (the decoder before issue 11/13) in the same run, plus PNG and
HEIC for reference. CPU time (time.process_time) per decode: median, p10 / p90.
"""

from __future__ import annotations

import argparse
import io
import os
import sys
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from bench.common import EVAL_DIR, fmt, pin_one_core, stats  # noqa: E402
from findme_io.imageio import decode_image  # noqa: E402


def base_image() -> np.ndarray:
    p = EVAL_DIR / "views" / "zt_r01_p14_v1.jpg"
    if p.exists():
        return cv2.imread(str(p))
    from findme_core.synth.render import Pose, Room, render
    return render(Room.rectangle(5.0, 6.0), Pose(0.2, -1.5, 1.45, yaw_deg=20), 640, 480,
                  hfov_deg=70.0).image


def cpu_ms(fn, data, repeat):
    out = []
    for _ in range(repeat):
        t = time.process_time()
        fn(data)
        out.append(1e3 * (time.process_time() - t))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=15)
    a = ap.parse_args(argv)
    how = pin_one_core()
    from PIL import Image
    from findme_io.imageio import _pillow
    _pillow()
    base = base_image()
    cv = lambda d: cv2.imdecode(np.frombuffer(d, np.uint8), cv2.IMREAD_COLOR)  # noqa: E731
    print(f"decode CPU time per photo, {a.repeat} runs each, alternating, {how}")
    for (w, h) in ((640, 480), (4000, 3000)):
        img = cv2.resize(base, (w, h), interpolation=cv2.INTER_CUBIC)
        cases = {"jpeg": cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes(),
                 "png": cv2.imencode(".png", img)[1].tobytes()}
        buf = io.BytesIO()
        Image.fromarray(img[:, :, ::-1]).save(buf, format="HEIF", quality=90)
        cases["heic"] = buf.getvalue()
        for kind, data in cases.items():
            ours, base_ms = [], []
            for _ in range(a.repeat):      # interleaved: both see the same machine load
                ours += cpu_ms(decode_image, data, 1)
                if kind != "heic":
                    base_ms += cpu_ms(cv, data, 1)
            label = f"{kind} {w}x{h} ({len(data) / 1e6:.2f} MB)"
            print(fmt(f"{label}: ours (Pillow)", stats(ours)))
            if base_ms:
                print(fmt(f"{label}: cv2.imdecode", stats(base_ms)))


if __name__ == "__main__":
    main()
