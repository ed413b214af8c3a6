"""The phone page says when a photo does not look like a room view, with the reason: a
warning message and the photo's status line (the hypotheses stay, as guesses)."""

from __future__ import annotations

import cv2
import pytest

from findme_core.synth.render import Pose, Room, render

pytestmark = pytest.mark.timeout(120)


def test_a_top_down_photo_is_said_not_to_be_a_room(browser, app, shots, tmp_path):
    view = render(Room.rectangle(6, 6), Pose(0, 0, 1.4, 20, 88, 0))
    photo = tmp_path / "top-down.jpg"
    cv2.imwrite(str(photo), view.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
    context = browser.new_context(viewport={"width": 390, "height": 844},
                                  device_scale_factor=3, is_mobile=True, has_touch=True)
    page = context.new_page()
    try:
        page.goto(app.url)
        page.wait_for_selector('#status[data-state="connected"]')
        page.click("#settings summary")          # the phone's tilt, as its sensors give it
        for name, g in zip(("gx", "gy", "gz"), view.camera.gravity):
            page.fill(f"#{name}", f"{g:.6f}")
        page.set_input_files("#file-input", str(photo))
        page.wait_for_selector('#photo-status[data-not-room-view^="the camera looks 88° down"]')
        msg = page.locator('.msg[data-code="NOT_ROOM_VIEW"]')
        assert msg.count() == 1 and "does not look like a room" in msg.inner_text()
        assert "does not look like a room view" in page.inner_text("#photo-status")
        assert page.locator("#hyp-chips .chip").count() >= 1
        shots(page, "phone-390-not-a-room-view", at="#result")
    finally:
        context.close()
