"""The example and the benchmark scripts run end to end (on small meshes, to stay quick)."""

import os
import subprocess
import sys

import numpy as np
import pytest

import cfl
import reference
from conftest import MESHES, needs_mesh_files

# Both scripts read their meshes from files.
pytestmark = needs_mesh_files

HERE = os.path.dirname(os.path.abspath(__file__))
SWEEP = os.path.join(HERE, "..", "examples", "sweep.py")


def run(*args):
    return subprocess.run([sys.executable, *args], check=True, capture_output=True, text=True,
                          env=dict(os.environ)).stdout


def test_sweep_prints_a_profile_that_matches_distance(tmp_path):
    for name in ("torus", "patch"):
        reference.write_obj(tmp_path / f"{name}.obj", *MESHES[name])
    output = run(SWEEP, str(tmp_path / "torus.obj"), str(tmp_path / "patch.obj"), "--steps", "7", "--plot", "")
    rows = [line.split() for line in output.splitlines() if line[:4].strip().isdigit()]
    assert len(rows) == 7
    # Recompute the middle row's pose the way the script documents it and compare.
    a, b = cfl.Model(*MESHES["torus"]), cfl.Mesh(*MESHES["patch"])
    a_lo, a_hi = a.bounds
    b_lo, b_hi = b.bounds
    X_WB = np.eye(4)
    X_WB[:3, 3] = 0.5 * (a_lo + a_hi) - 0.5 * (b_lo + b_hi) + [0.0, 0.25 * (a_hi[1] - a_lo[1]), 0.0]
    assert float(rows[3][2]) == round(cfl.distance(a, None, b, X_WB).distance, 6)


def test_sweep_saves_a_plot_when_matplotlib_is_there(tmp_path):
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return
    for name in ("torus", "soup"):
        reference.write_obj(tmp_path / f"{name}.obj", *MESHES[name])
    plot = tmp_path / "profile.png"
    output = run(SWEEP, str(tmp_path / "torus.obj"), str(tmp_path / "soup.obj"), "--steps", "5", "--plot", str(plot))
    assert f"plot saved to {plot}" in output
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_overhead_benchmark_runs_and_both_sides_agree(tmp_path):
    reference_program = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(cfl.__file__))),
                                     "cfl_python_overhead_reference")
    if not os.path.exists(reference_program):
        pytest.skip("cfl_python_overhead_reference is not built")
    reference.write_obj(tmp_path / "torus.obj", *MESHES["torus"])
    output = run(os.path.join(HERE, "..", "bench", "bench_overhead.py"), "--mesh", str(tmp_path / "torus.obj"),
                 "--resolution", "10", "--poses", "64", "--single", "2", "--repeats", "3", "--blocks", "1",
                 "--rounds", "1")
    assert "overhead per pose" in output and "distances identical on both sides: yes" in output
