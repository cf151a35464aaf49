import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from negobs_gym.core import Pose
from negobs_gym.core.geometry import (
    PolygonsAhead,
    distance_to_polyline,
    heading_axes,
    lattice_in_polygon,
    pad_polygons,
    points_in_polygon,
    points_in_polygons,
    polygon_in_strip_y,
    polygon_outline_points,
    polyline_stations,
    project_onto_polyline,
    vehicle_to_world_xy,
    world_to_vehicle_xy,
)
from negobs_gym.errors import GeometryError, NegobsError

coord = st.floats(-1e3, 1e3, allow_nan=False)
yaw = st.floats(-10.0, 10.0, allow_nan=False)
points = arrays(np.float64, st.tuples(st.integers(0, 20), st.just(2)), elements=coord)

SQUARE = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
ELL = np.array([[0, 0], [3, 0], [3, 1], [1, 1], [1, 3], [0, 3]], float)


@settings(max_examples=200, deadline=None)
@given(points, coord, coord, yaw)
def test_frame_round_trip(pts, x, y, yaw_rad):
    back = world_to_vehicle_xy(vehicle_to_world_xy(pts, (x, y), yaw_rad), (x, y), yaw_rad)
    np.testing.assert_allclose(back, pts, atol=1e-9 * (1 + np.abs(pts).max(initial=0) + abs(x) + abs(y)))


@settings(max_examples=100, deadline=None)
@given(points, coord, coord, yaw)
def test_frames_agree_with_pose_and_heading(pts, x, y, yaw_rad):
    pose = Pose(x=x, y=y, yaw=yaw_rad)
    z = np.zeros((len(pts), 1))
    expected = pose.to_world(np.hstack([pts, z]))[:, :2]
    np.testing.assert_allclose(vehicle_to_world_xy(pts, (x, y), yaw_rad), expected, atol=1e-6)
    fwd, right = heading_axes(yaw_rad)
    np.testing.assert_allclose(fwd, pose.heading)
    # a point 1 m ahead and 1 m right in the vehicle frame lands at origin + fwd + right
    np.testing.assert_allclose(  # atol: (sin + cos) + y loses a tiny sin to rounding (yaw ~ 1e-282)
        vehicle_to_world_xy(np.array([[1.0, 1.0]]), (x, y), yaw_rad)[0],
        np.array([x, y]) + fwd + right,
        atol=1e-9 * (1 + abs(x) + abs(y)),
    )


def test_frame_known_values_and_shapes():
    # yaw +90 deg: the vehicle faces world -X, its right is world +Y
    np.testing.assert_allclose(
        vehicle_to_world_xy(np.array([[0.0, 1.0], [1.0, 0.0]]), (10.0, 0.0), math.pi / 2),
        [[9.0, 0.0], [10.0, 1.0]],
        atol=1e-12,
    )
    assert world_to_vehicle_xy(np.zeros((3, 4, 2)), (0, 0), 0.3).shape == (3, 4, 2)
    assert world_to_vehicle_xy(np.zeros((0, 2)), (0, 0), 0.3).shape == (0, 2)
    with pytest.raises(GeometryError, match="points_world"):
        world_to_vehicle_xy(np.zeros((3, 3)), (0, 0), 0.0)
    with pytest.raises(GeometryError, match="frame"):
        vehicle_to_world_xy(np.zeros((3, 2)), (0, np.nan), 0.0)


def test_points_in_polygons_square_and_concave():
    polys = pad_polygons([SQUARE, ELL])
    assert polys.shape == (2, 6, 2)
    pts = np.array([[0.5, 0.5], [2.5, 0.5], [2, 2.5], [0.5, 2.5], [-1, 1], [5, 5], [np.nan, 1.0]], float)
    got = points_in_polygons(pts, polys)
    expected = np.array(
        [[1, 1], [0, 1], [0, 0], [0, 1], [0, 0], [0, 0], [0, 0]],
        dtype=bool,
    )
    np.testing.assert_array_equal(got, expected)
    assert points_in_polygons(pts, pad_polygons([])).shape == (7, 0)
    assert points_in_polygons(np.zeros((0, 2)), polys).shape == (0, 2)
    assert points_in_polygons(pts[:6].reshape(2, 3, 2), polys).shape == (2, 3, 2)


def test_points_in_polygon_single():
    pts = np.array([[1.0, 1.0], [3.0, 1.0], [1.0, -0.5], [0.5, 1.9]])
    assert points_in_polygon(pts, SQUARE).tolist() == [True, False, False, True]
    assert points_in_polygon(pts.reshape(2, 2, 2), SQUARE).shape == (2, 2)
    assert points_in_polygon(np.zeros((0, 2)), SQUARE).shape == (0,)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 12))
def test_lattice_in_polygon_equals_points_in_polygon_of_the_lattice(seed, vertices):
    """A star-shaped polygon of random radii (concave in general) against a lattice whose points
    fall on its vertices' coordinates and beside them: the row-wise crossings give the same mask."""
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0, 2 * np.pi, vertices))
    radii = rng.uniform(0.3, 2.0, vertices)
    polygon = np.round(np.column_stack([radii * np.cos(angles), radii * np.sin(angles)]), 1)
    xs, ys = np.arange(-2.1, 2.2, 0.1), np.arange(-2.05, 2.1, 0.1)
    if len(np.unique(polygon, axis=0)) < 3:
        return
    xx, yy = np.meshgrid(xs, ys)
    expected = points_in_polygon(np.stack([xx, yy], axis=-1), polygon)
    got = lattice_in_polygon(xs, ys, polygon)
    assert got.shape == (len(ys), len(xs))
    np.testing.assert_array_equal(got, expected)
    assert lattice_in_polygon(xs[:0], ys, polygon).shape == (len(ys), 0)


@settings(max_examples=200, deadline=None)
@given(
    arrays(np.float64, (30, 2), elements=st.floats(-3, 3, allow_nan=False)),
    st.floats(0.1, 5.0),
    st.floats(0.1, 5.0),
    coord,
    coord,
    yaw,
)
def test_rotated_rectangle_matches_vehicle_frame_bounds(pts_v, half_w, half_l, x, y, yaw_rad):
    """A rectangle built in the vehicle frame contains exactly the points inside its bounds there."""
    rect_v = np.array([[-half_w, -half_l], [half_w, -half_l], [half_w, half_l], [-half_w, half_l]])
    rect_w = vehicle_to_world_xy(rect_v, (x, y), yaw_rad)
    pts_w = vehicle_to_world_xy(pts_v, (x, y), yaw_rad)
    margin = 1e-6 * (1 + abs(x) + abs(y))
    clear = (np.abs(np.abs(pts_v[:, 0]) - half_w) > margin) & (np.abs(np.abs(pts_v[:, 1]) - half_l) > margin)
    expected = (np.abs(pts_v[:, 0]) < half_w) & (np.abs(pts_v[:, 1]) < half_l)
    got = points_in_polygon(pts_w, rect_w)
    np.testing.assert_array_equal(got[clear], expected[clear])


@pytest.mark.parametrize(
    "bad",
    [np.zeros((2, 2)), np.zeros((4, 3)), np.zeros(6), np.array([[0, 0], [1, np.nan], [0, 1.0]])],
)
def test_bad_polygons_raise(bad):
    with pytest.raises(GeometryError, match=r"outline_xy_m\[0\]"):
        pad_polygons([bad], name="outline_xy_m")
    with pytest.raises(GeometryError, match="polygon_xy"):
        points_in_polygon(np.zeros((1, 2)), bad)
    assert issubclass(GeometryError, NegobsError) and issubclass(GeometryError, ValueError)


def test_bad_points_raise():
    with pytest.raises(GeometryError, match="points_xy"):
        points_in_polygon(np.zeros((3, 3)), SQUARE)
    with pytest.raises(GeometryError, match="polygons"):
        points_in_polygons(np.zeros((3, 2)), SQUARE)


def test_polyline_stations_and_projection_known():
    line = np.array([[0.0, 0.0], [0.0, 3.0], [4.0, 3.0]])
    np.testing.assert_allclose(polyline_stations(line), [0.0, 3.0, 7.0])
    pts = np.array([[1.0, 1.0], [2.0, 5.0], [-1.0, -1.0], [9.0, 3.0]])
    station, dist = project_onto_polyline(pts, line)
    np.testing.assert_allclose(station, [1.0, 5.0, 0.0, 7.0])
    np.testing.assert_allclose(dist, [1.0, 2.0, math.sqrt(2), 5.0])
    s0, d0 = project_onto_polyline(np.zeros((0, 2)), line)
    assert s0.shape == d0.shape == (0,)
    with pytest.raises(GeometryError, match="polyline_xy"):
        polyline_stations(line[:1])


def test_distance_to_polyline_is_the_projections_distance_up_to_its_maximum():
    rng = np.random.default_rng(2)
    line = np.cumsum(rng.normal(0.0, 0.3, (1500, 2)) + np.array([0.0, 0.1]), axis=0)  # a long winding line
    pts = rng.uniform(line.min(axis=0) - 5.0, line.max(axis=0) + 5.0, (3000, 2))
    _, want = project_onto_polyline(pts, line)
    np.testing.assert_array_equal(distance_to_polyline(pts, line), want)
    for max_m in (4.6, 0.5, 0.0):
        got = distance_to_polyline(pts.reshape(60, 50, 2), line, max_m).ravel()
        within = want <= max_m
        np.testing.assert_array_equal(got[within], want[within])
        assert (got[~within] > max_m).all()
    assert distance_to_polyline(np.zeros((0, 2)), line).shape == (0,)
    for bad in (-1.0, math.nan):
        with pytest.raises(GeometryError, match="max_distance_m"):
            distance_to_polyline(pts, line, bad)


@settings(max_examples=200, deadline=None)
@given(
    arrays(np.float64, st.tuples(st.integers(2, 8), st.just(2)), elements=st.floats(-50, 50)),
    st.floats(0.0, 1.0),
)
def test_points_on_polyline_project_to_their_station(line, frac):
    """A point on the polyline at station s projects back to distance 0 (and station s when unique)."""
    stations = polyline_stations(line)
    s = frac * stations[-1]
    p = np.array([np.interp(s, stations, line[:, 0]), np.interp(s, stations, line[:, 1])])
    station, dist = project_onto_polyline(p, line)
    assert dist == pytest.approx(0.0, abs=1e-6)
    assert 0.0 <= station <= stations[-1] + 1e-9
    # the projected station maps back onto the same point (it may differ where the line crosses itself)
    q = np.array([np.interp(station, stations, line[:, 0]), np.interp(station, stations, line[:, 1])])
    np.testing.assert_allclose(q, p, atol=1e-6)


def test_polygon_in_strip_y_clips_edges_to_the_strip():
    wide = np.array([[-3.0, 10.0], [3.0, 10.0], [3.0, 10.4], [-3.0, 10.4]])  # no vertex in the strip
    assert sorted(set(polygon_in_strip_y(wide, 1.8))) == [10.0, 10.4]
    inside = np.array([[-0.5, 5.0], [0.5, 5.0], [0.5, 6.0], [-0.5, 6.0]])
    assert sorted(set(polygon_in_strip_y(inside, 1.8))) == [5.0, 6.0]
    beside = np.array([[3.0, 5.0], [4.0, 5.0], [4.0, 6.0], [3.0, 6.0]])
    assert polygon_in_strip_y(beside, 1.8).size == 0
    slanted = np.array([[-5.0, 20.0], [5.0, 10.0], [6.0, 11.0]])  # long edge crosses at y 13.2-16.8
    assert min(polygon_in_strip_y(slanted, 1.8)) == pytest.approx(13.2)
    with pytest.raises(GeometryError):
        polygon_in_strip_y(np.array([[0.0, 1.0], [np.nan, 2.0], [1.0, 1.0]]), 1.0)


def _random_polygon(rng: np.random.Generator) -> np.ndarray:
    """A rotated rectangle or triangle, 0.3-3 m across, somewhere within 30 m of the origin."""
    corners = 3 if rng.random() < 0.3 else 4
    angles = np.sort(rng.uniform(0.0, 2 * np.pi, corners))
    radius = rng.uniform(0.3, 3.0, corners)
    return rng.uniform(-30.0, 30.0, 2) + np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)


def test_polygons_ahead_equal_the_nearest_over_every_polygon():
    """Skipping the polygons whose bounding circle misses the strip ahead changes no answer."""
    rng = np.random.default_rng(7)
    found = 0
    for _ in range(60):
        polygons = [_random_polygon(rng) for _ in range(rng.integers(1, 25))]
        ahead = PolygonsAhead(polygons)
        for _ in range(10):
            origin, yaw = rng.uniform(-20.0, 20.0, 2), float(rng.uniform(-np.pi, np.pi))
            half = float(rng.uniform(0.5, 3.0))
            brute = math.inf
            for polygon in polygons:
                y = polygon_in_strip_y(world_to_vehicle_xy(polygon, origin, yaw), half)
                if (y > 0).any():
                    brute = min(brute, float(y[y > 0].min()))
            assert ahead.nearest_ahead(origin, yaw, half) == brute
            found += math.isfinite(brute)
    assert found > 100  # most draws have something ahead, and the test compares distances
    assert PolygonsAhead([]).nearest_ahead(np.zeros(2), 0.0, 1.0) == math.inf
    with pytest.raises(GeometryError):
        PolygonsAhead([np.array([[0.0, 0.0], [1.0, np.nan], [1.0, 1.0]])])


def _on_outline(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance of each point to the nearest edge of the closed polygon."""
    closed = np.vstack([polygon, polygon[:1]])
    return np.array([distance_to_polyline(p[None], closed)[0] for p in points])


def test_polygon_outline_points_walk_every_edge_at_most_the_spacing_apart():
    rng = np.random.default_rng(3)
    for _ in range(30):
        polygon = _random_polygon(rng)
        spacing = float(rng.uniform(0.02, 0.5))
        pts = polygon_outline_points(polygon, spacing)
        gaps = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
        assert gaps.max() <= spacing + 1e-12  # consecutive points, the last back to the first
        assert np.allclose(_on_outline(pts, polygon), 0.0, atol=1e-9)
        assert all(np.any(np.all(pts == v, axis=1)) for v in polygon)  # every vertex, exactly
        perimeter = np.hypot(*np.diff(np.vstack([polygon, polygon[:1]]), axis=0).T).sum()
        assert len(pts) <= len(polygon) + perimeter / spacing
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(GeometryError, match="spacing_m"):
            polygon_outline_points(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), bad)


def test_polygons_ahead_outline_points_are_in_the_vehicle_frame():
    square = np.array([[10.0, 20.0], [11.0, 20.0], [11.0, 21.0], [10.0, 21.0]])
    ahead = PolygonsAhead([square, square + 5.0])
    origin, yaw = np.array([10.5, 15.0]), 0.3
    pts = ahead.outline_points(origin, yaw, 0.1)
    world = np.vstack([polygon_outline_points(p, 0.1) for p in (square, square + 5.0)])
    assert np.allclose(pts, world_to_vehicle_xy(world, origin, yaw))
    assert np.array_equal(ahead.outline_points(origin, yaw, 0.1), pts)  # sampled once, same answer
    assert PolygonsAhead([]).outline_points(origin, yaw, 0.1).shape == (0, 2)
