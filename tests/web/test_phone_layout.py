"""The phone page's first screen, in headless Chromium at phone widths (360-430 px): the
take-photo button and the camera height are visible without scrolling; lens, phone tilt and
phone model wait under "More settings"; nothing is wider than the screen and no menu's
text is cut off, with the settings closed or open; after a photo the result is on screen."""

from __future__ import annotations

from importlib import resources

import pytest

pytestmark = pytest.mark.timeout(120)

ROOM_A = str(resources.files("findme") / "examples" / "room_a.jpg")
PHONES = {"360x740": (360, 740), "390x844": (390, 844), "430x932": (430, 932)}

#: every visible element wider than the screen, and every select whose longest option is
#: wider than the text room the select has (its width less padding and the arrow)
OVERFLOW_JS = """() => {
  const W = document.documentElement.clientWidth, out = [];
  for (const e of document.querySelectorAll('body *')) {
    const r = e.getBoundingClientRect(), st = getComputedStyle(e);
    if (!r.width || st.visibility === 'hidden' || e.classList.contains('file')) continue;
    if (r.left < -0.5 || r.right > W + 0.5) out.push(`${e.tagName}#${e.id}.${e.className}: ${r.left}-${r.right} of ${W}`);
  }
  const ctx = document.createElement('canvas').getContext('2d');
  for (const s of document.querySelectorAll('select')) {
    if (!s.getBoundingClientRect().width) continue;
    const st = getComputedStyle(s);
    ctx.font = `${st.fontWeight} ${st.fontSize} ${st.fontFamily}`;
    const room = s.clientWidth - parseFloat(st.paddingLeft) - parseFloat(st.paddingRight) - 20;
    for (const o of s.options) {
      const w = ctx.measureText(o.text).width;
      if (w > room) out.push(`select#${s.id} option "${o.text}": ${w.toFixed(0)} px > ${room.toFixed(0)} px`);
    }
  }
  if (document.documentElement.scrollWidth > W) out.push(`page ${document.documentElement.scrollWidth} > ${W}`);
  return out; }"""


def _phone(browser, app, size):
    w, h = size
    context = browser.new_context(viewport={"width": w, "height": h}, device_scale_factor=3,
                                  is_mobile=True, has_touch=True)
    page = context.new_page()
    page.goto(app.url)
    page.wait_for_selector('#status[data-state="connected"]')
    return page


def _on_screen(page, selector) -> bool:
    return page.evaluate("""s => { const r = document.querySelector(s).getBoundingClientRect();
        return r.width > 0 && r.top >= 0 && r.bottom <= innerHeight && r.left >= 0
               && r.right <= document.documentElement.clientWidth; }""", selector)


@pytest.mark.parametrize("phone", sorted(PHONES))
def test_first_screen_is_the_camera_button_and_height(browser, app, shots, phone):
    page = _phone(browser, app, PHONES[phone])
    try:
        assert page.evaluate("scrollY") == 0
        assert _on_screen(page, 'label[for="camera-input"]'), "take-photo button off screen"
        assert _on_screen(page, "#height"), "camera height off screen"
        assert not page.evaluate("document.getElementById('settings').open")
        for hidden in ("#lens", "#gx", "#device"):          # under "More settings"
            assert not page.is_visible(hidden), hidden
        assert page.evaluate(OVERFLOW_JS) == []
        if phone == "390x844":
            shots(page, "phone-390-first-screen")
        page.click("#settings summary")
        page.select_option("#lens", "intrinsics")
        assert page.is_visible("#gx") and page.is_visible("#lens")
        assert page.evaluate(OVERFLOW_JS) == []
        if phone == "390x844":
            shots(page, "phone-390-more-settings", at="#settings")
    finally:
        page.context.close()


def test_after_a_photo_its_result_is_on_screen(browser, app, shots):
    page = _phone(browser, app, PHONES["390x844"])
    try:
        page.set_input_files("#file-input", ROOM_A)
        page.wait_for_selector('#frame[data-index="0"][data-scene-rank="1"]')
        assert _on_screen(page, "#result h2")
        assert page.evaluate("""() => { const r = document.getElementById('photo')
            .getBoundingClientRect(); return r.top >= 0 && r.top < innerHeight / 2; }""")
        assert page.evaluate(OVERFLOW_JS) == []
        shots(page, "phone-390-result")
    finally:
        page.context.close()
