"""The NumPy reference itself, on configurations with known answers and against dense point sampling."""

import numpy as np
import pytest

import reference

tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def td(A, B):
    return float(reference.triangle_distance(np.asarray(A, float)[None], np.asarray(B, float)[None])[0])


def test_parallel_triangles_are_their_gap_apart():
    assert td(tri, tri + [0.1, 0.1, 0.5]) == pytest.approx(0.5, abs=1e-15)


def test_vertex_above_interior_gives_its_height():
    B = np.array([[0.2, 0.2, 0.3], [0.2, 0.2, 2.0], [1.0, 1.0, 2.0]])
    assert td(tri, B) == pytest.approx(0.3, abs=1e-15)


def test_skew_edges_give_the_line_distance():
    # Edge x-axis [0,1]x{0}x{0} of A against a segment along y at x=0.5, z=0.2, the third corner far up.
    B = np.array([[0.5, -1.0, -0.2], [0.5, 1.0, -0.2], [0.5, 0.0, -3.0]])
    assert td(tri + [0, 0, 0], B - [0, 0, 0]) == pytest.approx(0.2, abs=1e-15)


def test_piercing_triangles_are_at_zero():
    B = np.array([[0.2, 0.2, -1.0], [0.3, 0.2, 1.0], [0.2, 0.3, 1.0]])
    assert td(tri, B) == 0.0


def test_coplanar_overlap_is_zero_and_coplanar_gap_is_the_gap():
    assert td(tri, tri + [0.2, 0.2, 0.0]) == 0.0
    assert td(tri, -tri + [-0.25, 0.0, 0.0]) == pytest.approx(0.25, abs=1e-15)


def test_degenerate_triangles_measure_as_segments_and_points():
    segment = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.5, 0.0, 1.0]])
    point = np.array([[0.3, 0.3, -2.0]] * 3)
    assert td(tri, segment) == pytest.approx(1.0, abs=1e-15)
    assert td(tri, point) == pytest.approx(2.0, abs=1e-15)


def test_rounded_collinear_triangle_is_measured_as_its_segment():
    # Rotating a collinear triangle leaves its cross product at rounding level rather than 0; the reference
    # once read that as a plane and reported a crossing far from the triangle.
    rng = np.random.default_rng(9)
    line = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [1.0, 1.0, 1.0]])
    for _ in range(200):
        R = reference.random_rotation(rng)
        B = line @ R.T + rng.normal(size=3)
        A = rng.normal(size=(3, 3)) * 0.3 + rng.normal(scale=2.0, size=3)
        t = np.linspace(0, 1, 20001)[:, None]
        sampled = reference.point_triangle_distance(B[0] + t * (B[2] - B[0]), *A).min()
        assert td(A, B) == pytest.approx(sampled, abs=1e-6)


def sample(T, n=40):
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    keep = u + v <= 1
    u, v = u[keep], v[keep]
    return T[0] + u[:, None] * (T[1] - T[0]) + v[:, None] * (T[2] - T[0])


def test_random_pairs_agree_with_dense_sampling():
    # Sampling gives an upper bound that converges from above: the reference must be below it and close.
    rng = np.random.default_rng(5)
    for _ in range(40):
        A = rng.normal(size=(3, 3))
        B = rng.normal(size=(3, 3)) + rng.normal(scale=1.5, size=3)
        exact = td(A, B)
        pa, pb = sample(A), sample(B)
        sampled = np.sqrt(((pa[:, None, :] - pb[None, :, :]) ** 2).sum(-1)).min()
        spacing = max(np.ptp(A, axis=0).max(), np.ptp(B, axis=0).max()) / 39
        assert exact <= sampled + 1e-12
        assert sampled - exact <= 2 * spacing
