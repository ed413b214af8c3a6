"""The selection image: the photo with every hypothesis drawn in its own colour, numbered.

Pure drawing (OpenCV on arrays); writing the PNG is the caller's business.
"""

from __future__ import annotations

import colorsys

import cv2
import numpy as np


def palette(n: int) -> list[tuple[int, int, int]]:
    """``n`` distinct, saturated BGR colours (golden-angle hues; rank 1 is green)."""
    out = []
    for i in range(n):
        h = (0.33 + i * 0.381966) % 1.0
        r, g, b = colorsys.hsv_to_rgb(h, 0.95, 1.0)
        out.append((int(b * 255), int(g * 255), int(r * 255)))
    return out


def _label_anchor(poly: np.ndarray, width: int, height: int, slot: float) -> tuple[int, int]:
    u = float(np.clip(slot * (width - 1), 12, width - 13))
    v = float(np.interp(u, poly[:, 0], poly[:, 1]))
    return int(round(u)), int(round(np.clip(v, 14, height - 6)))


def draw_hypotheses(image: np.ndarray, polylines, selected: int | None = None,
                    thickness: int | None = None) -> np.ndarray:
    """Draw numbered polylines over a copy of the photo.

    Args:
        image: (H, W, 3) uint8 BGR (or (H, W) grey); not modified.
        polylines: ranked sequence of (M, 2) pixel polylines, best first; number i + 1 is
            drawn for item i. They are drawn worst first, so that the best lies on top.
        selected: optional 0-based index drawn thicker and last (on top of all).
        thickness: line width in pixels (default scales with the image).
    Returns:
        (H, W, 3) uint8 BGR.
    """
    img = image.copy() if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    h, w = img.shape[:2]
    t = thickness or max(2, round(w / 320))
    cols = palette(len(polylines))
    order = [i for i in reversed(range(len(polylines))) if i != selected]
    if selected is not None and 0 <= selected < len(polylines):
        order.append(selected)
    font_scale = max(0.5, w / 1100)
    for i in order:
        poly = np.asarray(polylines[i], float).reshape(-1, 2)
        pts = np.round(poly * 16).astype(np.int32).reshape(-1, 1, 2)
        tt = t * 2 if i == selected else t
        cv2.polylines(img, [pts], False, (0, 0, 0), tt + 2, cv2.LINE_AA, shift=4)
        cv2.polylines(img, [pts], False, cols[i], tt, cv2.LINE_AA, shift=4)
        slot = 0.08 + 0.84 * ((i * 0.618034) % 1.0)
        au, av = _label_anchor(poly, w, h, slot)
        text = str(i + 1)
        (tw, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, font_scale, 2)
        x0, y0 = int(np.clip(au - tw // 2 - 3, 0, w - tw - 6)), int(np.clip(av - th - 8, 0, h - th - 6))
        cv2.rectangle(img, (x0, y0), (x0 + tw + 6, y0 + th + 6), cols[i], -1)
        cv2.putText(img, text, (x0 + 3, y0 + th + 2), cv2.FONT_HERSHEY_SIMPLEX, font_scale,
                    (0, 0, 0), 2, cv2.LINE_AA)
    return img
