import cv2
import numpy as np
import pytest

from findme_core.errors import GeometryError, HypothesisError, InputError
from findme_core.geometry.camera import Camera
from findme_core.single import tops
from findme_core.single.scene import REASONS, Scene, boundary_sigma_px, distances
from findme_core.single.search import SegKind
from findme_core.single.seen import floor_under, seen_px, shows_floor
from findme_core.synth.render import FLOOR, WALL_BASE


def _pixels(view, label_test, n=60, seed=0, margin=6):
    """Random pixels whose label passes ``label_test``, away from label changes."""
    lab = view.labels.astype(int)
    ok = label_test(lab)
    # stay clear of boundaries (the polyline is piecewise linear between columns)
    for dv in range(-margin, margin + 1):
        ok &= np.roll(lab, dv, axis=0) == lab
    for du in (-2, 2):
        ok &= np.roll(lab, du, axis=1) == lab
    vs, us = np.nonzero(ok)
    i = np.random.default_rng(seed).choice(len(us), size=min(n, len(us)), replace=False)
    return np.column_stack([us[i], vs[i]]).astype(float)


@pytest.mark.parametrize("fixture", ["level_view", "tilted_view"])
def test_floor_points_exact(fixture, request):
    view = request.getfixturevalue(fixture)
    scene = Scene(view.camera, view.camera_height, view.ground_truth_boundary_polyline())
    px = _pixels(view, lambda l: l == FLOOR)
    for p, q in zip(scene.locate(px), px):
        assert p.surface == "floor" and p.error is None
        truth = view.points_cam[int(q[1]), int(q[0])]
        assert np.allclose(p.xyz, truth, atol=1e-4)              # eq. 2, generalised
        assert p.sigma_parts["boundary"] == 0.0                   # the boundary does not move it
        assert p.sigma_parts["height"] == pytest.approx(np.linalg.norm(truth) * 0.03 /
                                                        view.camera_height, rel=1e-3)


@pytest.mark.parametrize("fixture", ["level_view", "tilted_view"])
def test_wall_points_on_the_wall(fixture, request):
    view = request.getfixturevalue(fixture)
    scene = Scene(view.camera, view.camera_height, view.ground_truth_boundary_polyline())
    px = _pixels(view, lambda l: (l >= WALL_BASE) & (l < 50))
    rel = []
    for p, q in zip(scene.locate(px), px):
        assert p.surface == "wall", (q, p.error)
        truth = view.points_cam[int(q[1]), int(q[0])]
        rel.append(np.linalg.norm(p.xyz - truth) / np.linalg.norm(truth))
        assert p.sigma_parts["boundary"] > 0
    assert np.max(rel) < 0.005  # eqs. 3-4: only the boundary's per-column sampling differs


def test_floor_point_above_horizon_is_an_error():
    cam = Camera.from_hfov(70, 640, 480)
    scene = Scene(cam, 1.5, [[0, 400], [639, 400]])
    with pytest.raises(GeometryError, match="horizon"):
        scene.floor_point((320, 200))
    assert scene.floor_point((320, 400))[1] == pytest.approx(1.5)
    p = scene.locate([(320, 100)])[0]            # above the horizon: on the front wall
    assert p.surface == "wall" and p.xyz[2] == pytest.approx(1.5 * cam.fy / (400 - cam.cy))


def _right_wall_scene(cam, h=1.5):
    """A single wall along the camera's forward axis, 1 m to the right (x = 1)."""
    pts = []
    for z in (2.0, 10.0):
        uv, _ = cam.project_cam([[1.0, h, z]])
        pts.append(uv[0])
    return Scene(cam, h, np.array(pts))


def test_ray_parallel_to_the_wall():
    cam = Camera.from_hfov(70, 640, 480)
    p = _right_wall_scene(cam).locate([(cam.cx, 100.0)])[0]   # straight ahead, above horizon
    assert p.xyz is None and "parallel" in p.error


def test_wall_behind_the_camera():
    cam = Camera.from_hfov(70, 640, 480)
    p = _right_wall_scene(cam).locate([(50.0, 100.0)])[0]     # looking left, above horizon
    assert p.xyz is None and "behind the camera" in p.error


def test_outside_image_and_nan():
    cam = Camera.from_hfov(70, 640, 480)
    scene = Scene(cam, 1.5, [[0, 400], [639, 400]])
    out = scene.locate([(-5, 10), (700, 10), (float("nan"), 3)])
    assert [p.xyz for p in out] == [None] * 3
    assert "outside the 640x480 image" in out[0].error and "not finite" in out[2].error


@pytest.mark.parametrize("said,msg", [
    (["floor"], "1 surfaces said for 2 pixels"),           # was applied to both pixels
    (["wall", "top", "floor"], "3 surfaces said for 2"),  # was a numpy broadcast error
    (["bogus", None], "surface 'bogus' is none of floor, wall, top"),   # was taken as unsaid
])
def test_what_is_said_is_one_surface_or_none_per_pixel(said, msg):
    scene = Scene(Camera.from_hfov(70, 640, 480), 1.5, [[0, 400], [639, 400]])
    with pytest.raises(InputError, match=msg):
        scene.locate([(320, 100), (320, 450)], said)
    got = scene.locate([(320, 100), (320, 450)], [None, "floor"])
    assert [p.surface for p in got] == ["wall", "floor"]


def test_open_and_none_segments():
    cam = Camera.from_hfov(70, 640, 480, (0, np.cos(0.6), np.sin(0.6)))  # looking down
    poly = [[0, -0.5], [300, -0.5], [300.5, 300], [639, 300]]
    kinds = [SegKind.OPEN, SegKind.STEP, SegKind.WALL]
    scene = Scene(cam, 1.2, poly, kinds)
    left, right_wall = scene.locate([(100, 50), (500, 100)])
    assert left.surface == "floor"                     # the floor continues past the top
    assert right_wall.surface == "wall"
    none = Scene(cam, 1.2, [[0, 479.5], [639, 479.5]], [SegKind.NONE])
    p = none.locate([(320, 200)])[0]
    assert p.xyz is None and "no floor is visible" in p.error


def test_rays_meet_the_pieces_in_blocks_with_the_same_answer(monkeypatch):
    """Memory is bounded by blocks of ray x piece pairs (a boundary may carry 4096 points on
    the bus); the pieces found, and so every answer, do not depend on them."""
    cam = Camera.from_hfov(70, 640, 480, (0, np.cos(0.5), np.sin(0.5)))
    u = np.linspace(0, 639, 40)
    poly = np.column_stack([u, 300 + 40 * np.sin(u / 50)])
    scene = Scene(cam, 1.4, poly, boundary_sigma_px=10.0)
    rng = np.random.default_rng(3)
    px = np.column_stack([rng.uniform(0, 639, 500), rng.uniform(0, 479, 500)])
    whole = scene.locate_level(px)
    assert len(set(scene._piece(scene._pieces, cam.rays_level(px)).tolist())) > 20
    for block in (1, 39, 1000):
        monkeypatch.setattr(tops, "BLOCK", block)
        points, surface, sigma, parts, reason = scene.locate_level(px)
        for a, b in zip((points, surface, sigma, reason), whole[:3] + whole[4:]):
            np.testing.assert_array_equal(a, b)
        for k, part in whole[3].items():
            np.testing.assert_array_equal(parts[k], part)


@pytest.mark.parametrize("args,exc,msg", [
    ((0.0, [[0, 400], [639, 400]]), GeometryError, "camera height"),
    ((float("nan"), [[0, 400], [639, 400]]), GeometryError, "camera height"),
    ((1.5, [[0, 400]]), HypothesisError, "at least 2"),
    ((1.5, [[0, 100], [639, 100]]), HypothesisError, "horizon"),
])
def test_degenerate_scenes(args, exc, msg):
    cam = Camera.from_hfov(70, 640, 480)
    with pytest.raises(exc, match=msg):
        Scene(cam, *args)
    with pytest.raises(HypothesisError, match="segment kinds"):
        Scene(cam, 1.5, [[0, 400], [639, 400]], [SegKind.WALL, SegKind.WALL])


def test_distances_and_sigmas(level_view):
    scene = Scene(level_view.camera, level_view.camera_height,
                  level_view.ground_truth_boundary_polyline())
    a, b, c = scene.locate([(320, 470), (200, 440), (-9, 0)])
    d = distances([a, b, c], scene.height, scene.height_sigma)
    assert d[0][0] == pytest.approx(np.linalg.norm(a.xyz - b.xyz))
    assert d[0][1] >= d[0][0] * scene.height_sigma / scene.height
    assert d[1] == (None, None, "an end point has no 3D position")
    # a point further away is less certain (one pixel covers more floor)
    near, far = scene.locate([(320, 470), (320, 420)])
    assert far.sigma_m > near.sigma_m


def _tilted(cam, d_pitch):
    """The camera with gravity pitched down by ``d_pitch`` radians more (about level x)."""
    R = cam.R_level_from_cam
    w = d_pitch * R[0]
    Rw, _ = cv2.Rodrigues(w.reshape(3, 1))
    return cam.with_gravity(Rw @ cam.gravity)


def test_gravity_sigma_part(tilted_view):
    """The 'gravity' part is the point's displacement under a 1-sigma tilt (checked against
    the scene rebuilt with the tilted gravity); exact gravity gives 0 and no jacobian."""
    view = tilted_view
    poly = view.ground_truth_boundary_polyline()
    px = _pixels(view, lambda l: l == FLOOR, n=8) + 0.0
    exact = Scene(view.camera, view.camera_height, poly)
    assert all(p.sigma_parts["gravity"] == 0 and p.gravity_jac is None for p in exact.locate(px))
    s = np.radians(0.5)
    scene = Scene(view.camera, view.camera_height, poly, gravity_cov=np.diag([s * s, 0.0]))
    moved = Scene(_tilted(view.camera, s), view.camera_height, poly)
    for p, q in zip(scene.locate(px), moved.locate(px)):
        d = np.linalg.norm(q.xyz - p.xyz)
        assert p.sigma_parts["gravity"] == pytest.approx(d, rel=0.05)
        assert p.sigma_m ** 2 == pytest.approx(sum(v * v for v in p.sigma_parts.values()))
    iso = Scene(view.camera, view.camera_height, poly, gravity_cov=np.eye(2) * s * s)
    assert all(a.sigma_parts["gravity"] > b.sigma_parts["gravity"]
               for a, b in zip(iso.locate(px), scene.locate(px)))   # roll adds to it


def test_gravity_part_of_a_distance_is_correlated(tilted_view):
    """Both ends move together under a tilt: the distance's gravity part is the change of
    the distance itself, not the two points' parts added up."""
    view = tilted_view
    poly = view.ground_truth_boundary_polyline()
    a, b = _pixels(view, lambda l: l == FLOOR, n=2, seed=5)
    s = np.radians(1.0)
    kw = dict(height_sigma=0.0, gravity_cov=np.diag([s * s, 0.0]))
    pa, pb = Scene(view.camera, view.camera_height, poly, **kw).locate([a, b])
    (d, sd, err), = distances([pa, pb], view.camera_height, 0.0)
    qa, qb = Scene(_tilted(view.camera, s), view.camera_height, poly).locate([a, b])
    change = abs(np.linalg.norm(qb.xyz - qa.xyz) - d)
    rest = np.sqrt(sum(p.sigma_parts[k] ** 2 for p in (pa, pb) for k in ("boundary", "pixel")))
    assert err is None and sd == pytest.approx(np.hypot(change, rest), rel=0.05)
    assert change < pa.sigma_parts["gravity"] + pb.sigma_parts["gravity"]


def test_nonfinite_gravity_cov_is_refused(tilted_view):
    with pytest.raises(GeometryError, match="gravity_cov"):
        Scene(tilted_view.camera, 1.4, [[0, 300], [639, 300]], gravity_cov=[[np.nan, 0], [0, 1]])


def test_boundary_near_the_horizon_places_no_wall_point(level_view):
    """A wrong boundary just below the horizon (a counter's edge taken for the floor line):
    a pixel there is worth metres, so the wall points above it are not placed (None with
    the reason) rather than put tens of metres away; the true boundary places them."""
    view = level_view
    cam = view.camera
    sigma_px = boundary_sigma_px(cam.width, cam.height)
    px = _pixels(view, lambda l: (l >= WALL_BASE) & (l < 50), n=40, seed=3)
    px = px[px[:, 1] < cam.cy - 10]              # above the wrong boundary
    wrong = Scene(cam, view.camera_height, [[0, cam.cy + 4], [cam.width - 1, cam.cy + 4]],
                  boundary_sigma_px=sigma_px)
    located = wrong.locate(px)
    assert all(p.xyz is None and "too loosely" in p.error for p in located)
    # without the limit the same points get a position (far off) with their large sigma
    free = Scene(cam, view.camera_height, [[0, cam.cy + 4], [cam.width - 1, cam.cy + 4]],
                 boundary_sigma_px=sigma_px, max_rel_sigma=None).locate(px)
    truth = view.points_cam[px[:, 1].astype(int), px[:, 0].astype(int)]
    assert all(p.surface == "wall" and p.sigma_m > 0.5 * np.linalg.norm(p.xyz) for p in free)
    assert all(np.linalg.norm(p.xyz - t) > np.linalg.norm(t) for p, t in zip(free, truth))
    right = Scene(cam, view.camera_height, view.ground_truth_boundary_polyline(),
                  boundary_sigma_px=sigma_px).locate(px)
    for p, t in zip(right, truth):
        assert p.surface == "wall" and p.sigma_m <= 0.5 * np.linalg.norm(p.xyz)
        assert np.linalg.norm(p.xyz - t) < 0.005 * np.linalg.norm(t)
    P, surface, sigma, _, reason = wrong.locate_level(px)   # the vectorised form agrees
    assert np.all(np.isnan(P)) and np.all(surface == 0) and np.all(np.isinf(sigma))
    assert np.all(reason == next(k for k, t in REASONS.items() if "too loosely" in t))


def test_steep_boundary_has_its_sideways_sigma():
    """The base of a wall running away from the camera is steep in the image: moved down it
    slides along itself, so the boundary part is the sideways move's displacement (it was
    near 0 before); the point itself is exact."""
    cam = Camera.from_hfov(70, 640, 480)
    h, x = 1.5, 0.4                                  # a wall 0.4 m to the right, along z
    poly, _ = cam.project_cam([[x, h, 1.6], [x, h, 12.0]])
    scene = Scene(cam, h, poly)
    assert abs(np.diff(poly[:, 1])[0]) > 2 * abs(np.diff(poly[:, 0])[0])   # steep
    z = 4.0
    uv, _ = cam.project_cam([[x, 0.5, z]])           # a wall pixel 1 m above the floor
    p = scene.locate(uv)[0]
    assert p.surface == "wall" and np.allclose(p.xyz, [x, 0.5, z], atol=1e-6)

    def moved(shift):
        q = Scene(cam, h, poly + shift, max_rel_sigma=None).locate(uv)[0]
        return np.linalg.norm(q.xyz - p.xyz)
    down, side = moved([0.0, 1.0]), moved([1.0, 0.0])
    assert side > 3 * down
    assert p.sigma_parts["boundary"] == pytest.approx(side, rel=0.02)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_max_rel_sigma_must_be_positive(bad):
    cam = Camera.from_hfov(70, 640, 480)
    with pytest.raises(GeometryError, match="max_rel_sigma"):
        Scene(cam, 1.5, [[0, 400], [639, 400]], max_rel_sigma=bad)


def test_a_tap_said_to_be_on_the_floor_is_put_on_it_whatever_the_boundary(tilted_view):
    """A wrong boundary 60 px below the true one (a low cabinet's base taken for the floor
    line, the floor seen beyond it): floor pixels between the two are put on a wall; said to
    be floor, each is the rendered floor's point, its sigma with no boundary part, as a floor
    point's, with a note that the chosen line runs below it. A floor pixel below the wrong
    line, said floor or not, and a wall pixel carry no note."""
    view = tilted_view
    poly = view.ground_truth_boundary_polyline()
    wrong = Scene(view.camera, view.camera_height, poly + np.array([0.0, 60.0]))
    px = _pixels(view, lambda l: l == FLOOR, n=200)
    # floor pixels less than 60 px below the true boundary: the wrong one puts them on a wall
    under = px[[wrong.locate([q])[0].surface == "wall" for q in px]]
    assert len(under) >= 5
    auto = wrong.locate(under)
    said = wrong.locate(under, ["floor"] * len(under))
    off = []
    for q, a, s in zip(under, auto, said):
        truth = view.points_cam[int(q[1]), int(q[0])]
        off.append(np.linalg.norm(a.xyz - truth))             # on the wrong wall
        assert s.surface == "floor" and np.allclose(s.xyz, truth, atol=1e-4)
        assert s.sigma_parts["boundary"] == 0.0
        assert "floor line runs below this point" in s.note and "choose a hypothesis" in s.note
        assert a.note is None                                  # nothing said: nothing to note
    assert max(off) > 0.3
    below = px[[p.surface == "floor" for p in wrong.locate(px)]]
    assert len(below) >= 5
    assert all(p.surface == "floor" and p.note is None
               for p in wrong.locate(below, ["floor"] * len(below)))


def test_a_tap_said_to_be_on_a_wall_where_the_boundary_puts_floor_gets_no_answer(level_view):
    """Said "wall" on a pixel the boundary puts on the floor: no answer, with the reason and
    what to do; said "wall" on a wall pixel, or nothing said, changes nothing; said "floor"
    above the horizon: no answer."""
    view = level_view
    scene = Scene(view.camera, view.camera_height, view.ground_truth_boundary_polyline())
    floor = _pixels(view, lambda l: l == FLOOR, n=3)
    wall = _pixels(view, lambda l: (l >= WALL_BASE) & (l < 50), n=3)
    for p in scene.locate(floor, ["wall"] * 3):
        assert p.xyz is None and "choose a hypothesis" in p.error
    same = scene.locate(wall, ["wall", None, "wall"])
    for p, q in zip(same, scene.locate(wall)):
        assert p.surface == q.surface == "wall" and np.array_equal(p.xyz, q.xyz)
        assert p.sigma_m == q.sigma_m
    up = scene.locate([(320.0, 10.0)], ["floor"])[0]          # above a level camera's horizon
    assert up.xyz is None and "horizon" in up.error


def test_a_wall_whose_base_is_not_in_the_photo_is_not_measured():
    """A boundary continued below the image's bottom edge (its last segment wholly outside)
    puts a wall there that nobody saw the base of: ``locate`` refuses its points (every
    pixel of that column is above its base) and says why; the seen wall, the floor, a tap
    said to be on the floor and the lifting's ``locate_level`` are answered."""
    cam = Camera.from_hfov(70, 640, 480)
    poly = [[0, 400], [300, 470], [300.5, 500], [639, 600]]   # the last segment: v > 479
    scene = Scene(cam, 1.5, poly)
    seen, unseen, low, floor = scene.locate([(100, 200), (500, 200), (500, 470), (100, 450)])
    assert seen.surface == "wall" and seen.xyz is not None
    for p in (unseen, low):
        assert p.xyz is None and p.surface is None
        assert "outside the photo" in p.error and "not measured" in p.error
    assert floor.surface == "floor" and floor.xyz[1] == pytest.approx(1.5)
    said = scene.locate([(500, 200), (500, 470)], ["wall", "floor"])
    assert said[0].xyz is None and "outside the photo" in said[0].error
    assert said[1].surface == "floor"
    P, surface, _, _, reason = scene.locate_level([(500, 200)])
    assert reason[0] == 0 and surface[0] == 2 and np.isfinite(P[0]).all()


def test_a_wall_split_into_segments_is_seen_if_any_of_it_is():
    """One straight wall given as many short segments (a dense polyline), most of them
    below the image: the wall is seen, so every point on it is answered."""
    cam = Camera.from_hfov(70, 640, 480)
    u = np.arange(0.0, 640.0)
    poly = np.column_stack([u, 440 + 0.2 * u])      # crosses the bottom edge at u ~ 195
    scene = Scene(cam, 1.5, poly)
    out = scene.locate([(50, 200), (600, 200)])
    assert all(p.surface == "wall" for p in out), [p.error for p in out]


def test_a_segment_is_seen_where_it_crosses_the_image_rows():
    """``seen_px``: the length inside -0.5 <= v <= H - 0.5 (the last row's pixels reach
    H - 0.5), whatever the direction of the segment."""
    got = seen_px(np.array([[0, 479.3], [100, 479.3], [200, 479.6], [300, 579.5],
                            [400, 379.5], [500, -10.0], [639, 9.5]], float), 480)
    assert got[0] == pytest.approx(100.0)                       # in the last row
    assert got[2] == 0.0                                       # wholly below
    assert got[3] == pytest.approx(np.hypot(100, 200) / 2)      # half of it above 479.5
    assert got[4] == pytest.approx(np.hypot(100, 389.5) * 380 / 389.5)
    assert got[5] == pytest.approx(np.hypot(139, 19.5) * 10 / 19.5)   # from the top edge


def test_a_photo_showing_almost_no_floor_measures_no_wall():
    """A boundary hugging the photo's bottom edge (under 3 % of its height of floor in every
    column: ``room_view``'s "no floor-wall boundary in view"): no wall's foot is seen, so its
    wall points are refused with the reason, also when said to be on a wall; a pixel said
    floor is answered, and the lifting's ``locate_level`` answers the wall pixels. The same
    wall with floor in view is measured."""
    cam = Camera.from_hfov(70, 640, 480)
    sliver = Scene(cam, 1.5, [[0, 470], [639, 472]])
    assert not sliver.shows_floor
    wall, said_wall, said_floor = sliver.locate([(320, 200), (320, 300), (320, 475)],
                                                [None, "wall", "floor"])
    for p in (wall, said_wall):
        assert p.xyz is None and "almost no floor" in p.error and "step back" in p.error
    assert said_floor.surface == "floor" and said_floor.xyz is not None
    P, surface, _, _, reason = sliver.locate_level([(320, 200)])
    assert reason[0] == 0 and surface[0] == 2 and np.isfinite(P[0]).all()
    seen = Scene(cam, 1.5, [[0, 400], [639, 402]])
    assert seen.shows_floor and seen.locate([(320, 200)])[0].surface == "wall"


def test_the_floor_under_a_boundary_counts_columns_of_floor_in_view():
    """``seen.floor_under`` / ``shows_floor``: the share of the image's height under the
    boundary per sampled column, 0 on a NONE segment; the photo shows floor when at least
    10 % of its columns show at least 3 % of its height."""
    poly = np.array([[0, 240.0], [63.9, 240.0], [639, 479.5]])
    us, vs, kinds, floor = floor_under(poly, [SegKind.WALL, SegKind.WALL], 640, 480, columns=64)
    assert len(us) == 64 and np.all(np.diff(us) > 0)
    assert floor[0] == pytest.approx(0.5) and floor[-1] < 0.03
    assert shows_floor(poly, [SegKind.WALL, SegKind.WALL], 640, 480)
    none = [SegKind.NONE, SegKind.NONE]           # no floor in view anywhere
    assert np.all(floor_under(poly, none, 640, 480)[3] == 0.0)
    assert not shows_floor(poly, none, 640, 480)
    # floor in the first 7 of 64 sampled columns (10.9 %), then in the first 6 (9.4 %)
    W = [SegKind.WALL] * 3
    assert shows_floor([[0, 384], [70, 384], [70.5, 500], [639, 500]], W, 640, 480)
    assert not shows_floor([[0, 384], [60, 384], [60.5, 500], [639, 500]], W, 640, 480)
