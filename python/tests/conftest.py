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
    # Coarse grids keep the builds fast; queries are exact whatever the resolution, so nothing is lost.
    return {name: cfl.Model(v, f, resolution=12, threads=1) for name, (v, f) in MESHES.items()}


def diagonal(*vertex_arrays):
    points = np.vstack(vertex_arrays)
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
