"""Shared fixtures: small meshes of different kinds and their models (built once per test session)."""

import os

import numpy as np
import pytest

import cfl
import reference

# Model.from_file and Mesh.from_file need the module built with cfl::cfl_io (CFL_BUILD_IO, on by default).
needs_mesh_files = pytest.mark.skipif(not cfl._cfl._have_mesh_files, reason="built without CFL_BUILD_IO")

DATA_DIR = os.environ.get("CFL_DATA_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "data"))


def _meshes():
    rng = np.random.default_rng(33)
    return {
        "torus": reference.torus(),
        "patch": reference.wavy_patch(),
        "soup": reference.triangle_soup(rng),
    }


MESHES = _meshes()


@pytest.fixture(scope="session")
def meshes():
    return MESHES


@pytest.fixture(scope="session")
def models():
    # Coarse uniform grids (the paper's mode, 12 cells along the longest axis) keep the builds fast; queries
    # are exact whatever the regions, so nothing is lost.
    return {name: cfl.Model(v, f, resolution=12, threads=1) for name, (v, f) in MESHES.items()}


@pytest.fixture(scope="session")
def adaptive_models():
    # The default build: adaptive regions, refined where lists are long, some leaves without a list.
    return {name: cfl.Model(v, f, threads=1) for name, (v, f) in MESHES.items()}


def coarsened_model(vertices, faces):
    """An adaptive model of the mesh built under a memory_limit that stops its refinement (coarsened=True).

    The limit is searched downwards from what the unlimited build uses, since the bytes a mesh needs depend
    on the builder's tuning; a limit below what the unrefined root cells need is refused (ValueError).
    Returns (model, limit), or (None, None) when no limit coarsens the build (a mesh that does not refine).
    """
    full = cfl.Model(vertices, faces, threads=1)
    for limit in np.geomspace(full.memory_bytes, full.memory_bytes / 20, 40).astype(np.int64):
        try:
            model = cfl.Model(vertices, faces, threads=1, memory_limit=int(limit))
        except ValueError:
            break
        if model.coarsened:
            return model, int(limit)
    return None, None


def diagonal(*vertex_arrays):
    points = np.vstack(vertex_arrays)
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
