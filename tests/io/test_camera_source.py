"""A photo's hypotheses with its camera and gravity sources (findme_io.camera_source)."""

import math

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.methods import hypothesize
from findme_io.camera_source import hypothesize_photo, with_gravity


def level_camera(v):
    c = v.camera
    return Camera(c.fx, c.fy, c.cx, c.cy, c.width, c.height)


def test_an_exact_given_gravity_is_used_as_it_is(tilted_view):
    """Sigma 0: exact (a tripod, a dataset); any other given gravity is refined by the
    photo's lines (tests/core/single/test_gravity_fusion.py)."""
    v = tilted_view
    cam, prov = with_gravity(level_camera(v), v.image, v.camera.gravity, 0.0)
    assert prov.gravity == "input" and prov.estimate is None
    hs, cam2, prov2 = hypothesize_photo(v.image, cam, prov)
    ref = hypothesize(v.image, v.camera)
    assert cam2 is cam and prov2 is prov
    assert all(np.allclose(a.polyline, b.polyline) for a, b in zip(hs.hypotheses, ref.hypotheses))


def test_gravity_from_the_image_then_its_hypotheses(tilted_view):
    v = tilted_view
    cam, prov = with_gravity(level_camera(v), v.image)
    assert prov.gravity == "image" and prov.estimate is not None
    assert prov.estimate.segments is not None          # the hypotheses take these
    hs, cam2, prov2 = hypothesize_photo(v.image, cam, prov, max_n=3)
    assert 1 <= len(hs.hypotheses) <= 3
    err = math.degrees(math.acos(float(np.clip(cam2.gravity @ v.camera.gravity, -1, 1))))
    assert err < 0.3 and prov2.gravity == "image"
    assert np.allclose(cam2.gravity, prov2.estimate.vector)
    assert prov2.gravity_sigma > 0 and np.allclose(prov2.gravity_cov, prov2.estimate.cov)


def test_level_when_the_image_is_not_used(tilted_view):
    v = tilted_view
    cam, prov = with_gravity(level_camera(v), v.image, estimate=False)
    assert prov.gravity == "level" and prov.estimate is None and "level assumed" in prov.notes[-1]
    hs, cam2, _ = hypothesize_photo(v.image, cam, prov)
    assert np.allclose(cam2.gravity, (0, 1, 0))


def test_which_gravity_a_plan_states_its_sigmas_for(tilted_view):
    """``Provenance.gravity_kind``, as ``session_photos.final_gravity`` hands it to the plan
    (``PlanParams.image_gravity_models``): a given gravity taken as it is at no more than a
    phone held still's 1-sigma is exact; a sensor's refined by the photo's lines or given
    loosely is a sensor's; one found in the photo is the image's."""
    from findme_io.session_photos import final_gravity
    v = tilted_view
    cases = {"exact (sigma 0)": (v.camera.gravity, 0.0, v.image),
             "a phone held still, as it is": (v.camera.gravity, math.radians(0.5), None),
             "a phone in the hand, refined": (v.camera.gravity, math.radians(1.5), v.image),
             "a phone in the hand, as it is": (v.camera.gravity, math.radians(1.5), None),
             "from the image": (None, None, v.image)}
    got = {}
    for name, (g, s, img) in cases.items():
        cam, prov = with_gravity(level_camera(v), img, g, s)
        got[name] = (prov.gravity, final_gravity(v.image, cam, prov, 1.4, True).kind)
    assert got == {"exact (sigma 0)": ("input", "exact"),
                   "a phone held still, as it is": ("input", "exact"),
                   "a phone in the hand, refined": ("input+image", "sensor"),
                   "a phone in the hand, as it is": ("input", "sensor"),
                   "from the image": ("image", "image")}
