import numpy as np

from findme_io.overlay import draw_hypotheses, palette


def test_palette_distinct():
    cols = palette(10)
    assert len(set(cols)) == 10


def test_draws_every_hypothesis_without_touching_the_photo():
    img = np.full((240, 320, 3), 100, np.uint8)
    before = img.copy()
    polys = [np.array([[0, 200.0], [319, 180.0]]), np.array([[0, 100.0], [150, 120], [319, 90]])]
    out = draw_hypotheses(img, polys, selected=1)
    assert np.array_equal(img, before) and out.shape == img.shape
    for colour in palette(2):
        assert (out == colour).all(axis=2).sum() > 50   # each colour is visible
    assert draw_hypotheses(img[..., 0], []).shape == (240, 320, 3)


def test_the_best_hypothesis_is_drawn_on_top():
    """Rank 1 lies on top of the others where they overlap (they are drawn worst first);
    a selected one is drawn on top of all."""
    img = np.full((240, 320, 3), 100, np.uint8)
    line = np.array([[0, 120.0], [319, 120.0]])
    polys = [line, line.copy(), line.copy()]
    cols = palette(3)
    at = lambda out: tuple(int(x) for x in out[120, 160])  # noqa: E731
    assert at(draw_hypotheses(img, polys)) == cols[0]
    assert at(draw_hypotheses(img, polys, selected=2)) == cols[2]
