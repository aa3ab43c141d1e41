#!/usr/bin/python3
"""Sweep one mesh past another and print the distance profile (and plot it when matplotlib is there).

    PYTHONPATH=build/python /usr/bin/python3 python/examples/sweep.py data/bunny.obj data/wuson.obj --plot sweep.png

Mesh B slides along the world x axis through a line beside mesh A (offset sideways by --offset times A's
bounding-box height), from --span diagonals before A's center to --span after. A stays at the identity.
All poses go to cfl.distances in one batch, which spreads them over every core.
"""

import argparse
import os

import numpy as np

import cfl

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "data")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mesh_a", nargs="?", default=os.path.join(DATA, "bunny.obj"))
    parser.add_argument("mesh_b", nargs="?", default=os.path.join(DATA, "wuson.obj"))
    parser.add_argument("--steps", type=int, default=41)
    parser.add_argument("--span", type=float, default=1.0, help="half the sweep, in diagonals of A")
    parser.add_argument("--offset", type=float, default=0.25, help="sideways offset, in heights of A (y extent)")
    parser.add_argument("--plot", default="sweep.png", help="image file for the profile ('' for none)")
    args = parser.parse_args()

    a = cfl.Model.from_file(args.mesh_a, progress=True)  # the Voronoi regions: built once, a second or two
    b = cfl.Mesh.from_file(args.mesh_b)                   # the moving mesh needs none
    print(f"A: {os.path.basename(args.mesh_a)}, {a!r}")
    print(f"B: {os.path.basename(args.mesh_b)}, {b!r}")

    a_lo, a_hi = a.bounds
    b_lo, b_hi = b.bounds
    a_center, b_center = 0.5 * (a_lo + a_hi), 0.5 * (b_lo + b_hi)
    diagonal = float(np.linalg.norm(a_hi - a_lo))
    # X_WB: B's center on the sweep line, B not rotated; the translation moves B's own frame accordingly.
    along = np.linspace(-args.span, args.span, args.steps) * diagonal
    poses = np.tile(np.eye(4), (args.steps, 1, 1))
    poses[:, :3, 3] = a_center - b_center + np.array([0.0, args.offset * (a_hi[1] - a_lo[1]), 0.0])
    poses[:, 0, 3] += along

    result = cfl.distances(a, np.eye(4), b, poses)

    print(f"{'step':>4} {'x':>10} {'distance':>12} {'tri A':>6} {'tri B':>6}  closest point on A (world)")
    for i in range(args.steps):
        p = result.point_a[i]
        print(f"{i:4d} {along[i]:10.4f} {result.distance[i]:12.6f} {result.triangle_a[i]:6d} {result.triangle_b[i]:6d}"
              f"  ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f})")
    touching = np.flatnonzero(result.distance == 0)
    if touching.size:
        print(f"in contact at {touching.size} of {args.steps} steps, "
              f"between x = {along[touching[0]]:.4f} and {along[touching[-1]]:.4f}")
    else:
        closest = int(np.argmin(result.distance))
        print(f"never in contact; closest at x = {along[closest]:.4f}: {result.distance[closest]:.6f}")

    if args.plot:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            print("matplotlib not found (Debian: python3-matplotlib): no plot")
            return
        figure, axes = plt.subplots(figsize=(7, 3.5))
        axes.plot(along, result.distance, marker=".")
        axes.set_xlabel("x offset of B (mesh units)")
        axes.set_ylabel("minimum distance (mesh units)")
        axes.set_title(f"{os.path.basename(args.mesh_b)} sweeping past {os.path.basename(args.mesh_a)}")
        axes.grid(True, alpha=0.3)
        figure.tight_layout()
        figure.savefig(args.plot, dpi=120)
        print(f"plot saved to {args.plot}")


if __name__ == "__main__":
    main()
