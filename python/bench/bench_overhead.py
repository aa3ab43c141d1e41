#!/usr/bin/python3
"""What the Python binding costs on top of the C++ calls it makes.

Builds a Model of a mesh (the bunny by default), saves it, and times on the same file and the same random
poses of the mesh against itself:
  * single: cfl.distance(a, I, b, X_WB) against cfl::computeDistance(a, I, b, X_WB) from C++, per call, for
    each of the first --single poses (REPEATS calls in a row timed together, the median of BLOCKS blocks);
    the overhead is the per-pose difference, reported as its median over the poses;
  * batch: cfl.distances(a, I, b, poses) over all --poses poses against cfl::computeDistances from C++
    (the Python time includes converting the (N, 4, 4) array and building the result arrays).
The C++ side is the program cfl_python_overhead_reference, built beside the module. Rounds alternate C++
and Python so that a change in the machine's load reaches both; each figure is the median over rounds.
Both sides' batch distances are compared bit for bit.

    PYTHONPATH=build/python /usr/bin/python3 python/bench/bench_overhead.py
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import cfl


def random_poses(count, center, diagonal, reach, rng):
    """count poses X_WB of a mesh centered at `center`: uniformly random rotations about its center and
    offsets of up to `reach` diagonals in uniformly random directions."""
    q = rng.normal(size=(count, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    R = np.empty((count, 3, 3))
    R[:, 0] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1)
    R[:, 1] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1)
    R[:, 2] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)
    direction = rng.normal(size=(count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    offset = direction * (reach * diagonal * rng.random(count))[:, None]
    poses = np.zeros((count, 4, 4))
    poses[:, :3, :3] = R
    # p_W = R (p_B - c) + c + offset: rotation about the mesh's center, then the offset.
    poses[:, :3, 3] = center + offset - R @ center
    poses[:, 3, 3] = 1
    return poses


def time_python_single(a, b, poses, repeats, blocks):
    identity = np.eye(4)
    distance = cfl.distance
    clock = time.perf_counter_ns
    per_pose = []
    for X_WB in poses:
        block_ns = []
        for _ in range(blocks):
            start = clock()
            for _ in range(repeats):
                distance(a, identity, b, X_WB)
            block_ns.append((clock() - start) / repeats)
        per_pose.append(statistics.median(block_ns))
    return per_pose


def default_reference():
    # Beside the package in the build tree: build/python/cfl/ and build/python/cfl_python_overhead_reference.
    return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(cfl.__file__))),
                        "cfl_python_overhead_reference")


def main():
    data_dir = os.environ.get("CFL_DATA_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "data"))
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", default=os.path.join(data_dir, "bunny.obj"))
    parser.add_argument("--resolution", type=int, default=0)
    parser.add_argument("--poses", type=int, default=10000, help="batch size")
    parser.add_argument("--single", type=int, default=50, help="poses timed one call at a time")
    parser.add_argument("--repeats", type=int, default=200, help="calls per timed block")
    parser.add_argument("--blocks", type=int, default=5, help="timed blocks per pose")
    parser.add_argument("--rounds", type=int, default=3, help="alternating C++ / Python rounds")
    parser.add_argument("--threads", type=int, default=0, help="batch threads (0 = all)")
    parser.add_argument("--reach", type=float, default=0.6,
                        help="largest offset between the two copies, in diagonals (0.6: mostly overlapping)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--reference", default=default_reference(), help="the C++ timing program")
    args = parser.parse_args()
    if not os.path.exists(args.reference):
        sys.exit(f"{args.reference} not found: build it with cmake --build build --target cfl_python_overhead_reference")

    model = cfl.Model.from_file(args.mesh, resolution=args.resolution)
    lo, hi = model.bounds
    poses = random_poses(args.poses, 0.5 * (lo + hi), float(np.linalg.norm(hi - lo)), args.reach,
                         np.random.default_rng(args.seed))
    single = min(args.single, args.poses)

    with tempfile.TemporaryDirectory() as tmp:
        model_file = os.path.join(tmp, "model.cfl")
        poses_file = os.path.join(tmp, "poses.f64")
        distances_file = os.path.join(tmp, "distances.f64")
        model.save(model_file)
        poses.astype("<f8").tofile(poses_file)
        # The same file loaded twice on both sides, as the C++ program does.
        a, b = cfl.Model.load(model_file), cfl.Model.load(model_file)

        cpp_single, cpp_batch, py_single, py_batch = [], [], [], []
        for _ in range(args.rounds):
            output = subprocess.run([args.reference, model_file, model_file, poses_file, str(single), str(args.repeats),
                                     str(args.blocks), str(args.threads), distances_file],
                                    check=True, capture_output=True, text=True).stdout
            reference = json.loads(output)
            cpp_single.append(reference["single_ns"])
            cpp_batch.append(reference["batch_seconds"])
            cpp_distances = np.fromfile(distances_file, dtype="<f8")

            py_single.append(time_python_single(a, b, poses[:single], args.repeats, args.blocks))
            start = time.perf_counter()
            batch = cfl.distances(a, np.eye(4), b, poses, threads=args.threads)
            py_batch.append(time.perf_counter() - start)
            if not np.array_equal(batch.distance, cpp_distances):
                sys.exit("the Python and C++ batches answered differently")

    cpp_per_pose = np.median(np.array(cpp_single), axis=0)
    py_per_pose = np.median(np.array(py_single), axis=0)
    overhead = py_per_pose - cpp_per_pose
    cpp_batch_median, py_batch_median = statistics.median(cpp_batch), statistics.median(py_batch)

    print(f"mesh {os.path.basename(args.mesh)}: {model.triangle_count} triangles, resolution {model.resolution}; "
          f"{args.rounds} rounds, seed {args.seed}, reach {args.reach}")
    diag = float(np.linalg.norm(hi - lo))
    apart = batch.distance[batch.distance > 0]
    print(f"poses: {np.mean(batch.distance == 0):.0%} overlapping" + (
        f"; the others apart by a median {np.median(apart) / diag:.3f} and at most {apart.max() / diag:.3f} diagonals"
        if apart.size else ""))
    print(f"single call ({single} poses, median of {args.blocks} blocks of {args.repeats} calls per pose):")
    print(f"  C++ computeDistance  median {np.median(cpp_per_pose) / 1e3:8.3f} us per call")
    print(f"  Python cfl.distance  median {np.median(py_per_pose) / 1e3:8.3f} us per call")
    print(f"  overhead per pose    median {np.median(overhead) / 1e3:8.3f} us "
          f"(min {overhead.min() / 1e3:.3f}, max {overhead.max() / 1e3:.3f}; target <= 2 us)")
    print(f"batch of {args.poses} poses, threads={args.threads} (median of {args.rounds} rounds):")
    print(f"  C++ computeDistances {cpp_batch_median * 1e3:8.2f} ms   rounds: "
          + ", ".join(f"{t * 1e3:.2f}" for t in cpp_batch))
    print(f"  Python cfl.distances {py_batch_median * 1e3:8.2f} ms   rounds: "
          + ", ".join(f"{t * 1e3:.2f}" for t in py_batch))
    print(f"  ratio Python / C++   {py_batch_median / cpp_batch_median:8.3f} (target <= 1.10)")
    print("  distances identical on both sides: yes")


if __name__ == "__main__":
    main()
