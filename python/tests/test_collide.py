"""cfl.collide against the brute-force distance: colliding exactly when the reference distance is 0."""

import numpy as np
import pytest

import cfl
import reference
from conftest import MESHES, diagonal


@pytest.mark.parametrize("name_a,name_b", [("torus", "torus"), ("torus", "soup"), ("patch", "soup")])
def test_collide_agrees_with_brute_force(models, name_a, name_b):
    va, fa = MESHES[name_a]
    vb, fb = MESHES[name_b]
    scale = diagonal(va, vb)
    rng = np.random.default_rng(8)
    seen = set()
    for _ in range(16):
        X_WA, X_WB = reference.random_pose(rng, 0.3 * scale), reference.random_pose(rng, 0.9 * scale)
        expected, _, _ = reference.brute_force_distance(va, fa, X_WA, vb, fb, X_WB)
        if 0 < expected < 1e-9 * scale:
            continue  # touching within rounding: either answer is right
        result = cfl.collide(models[name_a], X_WA, cfl.Mesh(vb, fb), X_WB)
        assert result.colliding == (expected == 0) == bool(result)
        seen.add(result.colliding)
    assert seen == {True, False}, "the poses should cover both answers"


def test_contacts_are_points_of_both_triangles(models, meshes):
    v, f = meshes["torus"]
    X_WA = reference.rigid(reference.random_rotation(np.random.default_rng(9)))
    X_WB = X_WA @ reference.rigid(reference.random_rotation(np.random.default_rng(10)), [0.4, 0.0, 0.0])
    result = cfl.collide(models["torus"], X_WA, models["torus"], X_WB, max_contacts=10)
    assert result.colliding and 1 <= len(result.contacts) <= 10
    TA = reference.world_triangles(v, f, X_WA)
    TB = reference.world_triangles(v, f, X_WB)
    tolerance = 1e-9 * diagonal(v)
    for contact in result.contacts:
        assert reference.point_triangle_distance(contact.position, *TA[contact.triangle_a]) <= tolerance
        assert reference.point_triangle_distance(contact.position, *TB[contact.triangle_b]) <= tolerance
        assert float(reference.triangle_distance(TA[contact.triangle_a][None], TB[contact.triangle_b][None])[0]) == 0.0
    # max_contacts=0 answers the question without listing pairs.
    bare = cfl.collide(models["torus"], X_WA, models["torus"], X_WB, max_contacts=0)
    assert bare.colliding and bare.contacts == []
    far = cfl.collide(cfl.Mesh(v, f), X_WA, models["torus"], X_WA @ reference.rigid(t=[10.0, 0, 0]), max_contacts=5)
    assert not far and far.contacts == []
