#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""How fast iterations of edge projections bring a bake's edges into the strain band: the
strain limit's own iteration (Jacobi with Chebyshev acceleration, docs/method.md "Strain
limit") against red-black Gauss-Seidel with over-relaxation, by mean |strain| after N
iterations, on the cloth the limit starts from. An independent numpy reimplementation, with no
skin planes and every vertex free (a cloth database), to choose an iteration before building it.

    drivenshape bake --db DB --driver SHOT.pc2 --frames A-B --no-resolve -o PRE/c.####.exr
    scripts/validation/strain_iterations.py --bake 'PRE/c.####.exr' --frames A-B \\
        --rest driven_rest.obj [--limited 'LIM/c.####.exr']

--limited (a bake of the same frames with --no-resolve --strain-limit 0.01) checks the
reimplementation against the kernel's 24 iterations. Needs numpy and the drivenshape module
(PYTHONPATH=build/python). Exit status 0, 2 on a bad argument.
"""

import argparse
import sys

import numpy as np

import drivenshape

BAND = float(np.float32(0.01))  # the settings' 0.01, as float32 (strainLimitTables)
RELAXATION = 1.5  # src/pipeline/stages/strain_limit.cpp
RADIUS = 0.98
FROM = 2
ITERATIONS = 24  # the settings' strain_iterations default


def frames_of(text):
    first, last = (int(t) for t in text.split("-"))
    return range(first, last + 1)


def read_frames(pattern, frames):
    path = pattern.replace("####", "{:04d}")
    return np.stack([drivenshape.read_point_cache_exr(path.format(f))[0] for f in frames]).astype(
        np.float64)


def rest_edges(obj):
    """The OBJ's positions and its faces' edges (each once), as meshEdges() takes them."""
    points, edges = [], set()
    with open(obj) as f:
        for line in f:
            if line.startswith("v "):
                points.append([float(t) for t in line.split()[1:4]])
            elif line.startswith("f "):
                face = [int(t.split("/")[0]) - 1 for t in line.split()[1:]]
                for i, a in enumerate(face):
                    b = face[(i + 1) % len(face)]
                    edges.add((min(a, b), max(a, b)))
    points = np.array(points)
    edges = np.array(sorted(edges))
    return points, edges, np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)


class Cloth:
    def __init__(self, points, edges, lengths):
        self.edges, self.lengths = edges, lengths
        self.count = len(points)
        self.degree = np.bincount(edges.ravel(), minlength=self.count).astype(float)

    def strain(self, x):
        e = self.edges
        length = np.linalg.norm(x[:, e[:, 0]] - x[:, e[:, 1]], axis=2)
        return 100.0 * float(np.mean(np.abs(length / self.lengths - 1.0)))

    def corrections(self, x):
        """Each vertex's sum of its edges' half corrections towards the band."""
        e, rest = self.edges, self.lengths
        d = x[:, e[:, 1]] - x[:, e[:, 0]]
        length = np.linalg.norm(d, axis=2)
        target = np.clip(length, (1.0 - BAND) * rest, (1.0 + BAND) * rest)
        share = np.where(length > 0.0, 0.5 * (length - target) / np.maximum(length, 1e-30), 0.0)
        s = share[..., None] * d
        out = np.zeros_like(x)
        np.add.at(out, (slice(None), e[:, 0]), s)
        np.add.at(out, (slice(None), e[:, 1]), -s)
        return out

    def chebyshev(self, x0, iterations, radius=RADIUS, start=FROM):
        before, x, omega = x0.copy(), x0.copy(), 1.0
        step = (RELAXATION / self.degree)[None, :, None]
        for k in range(iterations):
            jacobi = x + step * self.corrections(x)
            if k >= start and radius > 0.0:
                rho2 = radius * radius
                omega = 2.0 / (2.0 - rho2) if k == start else 4.0 / (4.0 - rho2 * omega)
                jacobi = omega * (jacobi - before) + before
            before, x = x, jacobi
        return x

    def colours(self):
        neighbours = [[] for _ in range(self.count)]
        for a, b in self.edges:
            neighbours[a].append(b)
            neighbours[b].append(a)
        colour = -np.ones(self.count, int)
        for v in range(self.count):
            used = {colour[u] for u in neighbours[v] if colour[u] >= 0}
            c = 0
            while c in used:
                c += 1
            colour[v] = c
        return colour

    def gauss_seidel(self, x0, iterations, omega):
        colour = self.colours()
        x = x0.copy()
        for _ in range(iterations):
            for c in range(colour.max() + 1):
                mask = colour == c
                x[:, mask] += (omega / self.degree[mask])[None, :, None] * self.corrections(x)[:, mask]
        return x


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bake", required=True, help="the cloth before the limit: NAME.####.exr")
    ap.add_argument("--frames", required=True, type=frames_of, help="A-B")
    ap.add_argument("--rest", required=True, help="the driven rest OBJ")
    ap.add_argument("--limited", help="the same frames limited by the kernel (24 iterations)")
    args = ap.parse_args()
    cloth = Cloth(*rest_edges(args.rest))
    x0 = read_frames(args.bake, args.frames)
    if x0.shape[1] != cloth.count:
        sys.exit(f"strain_iterations: {args.bake} has {x0.shape[1]} vertices, {args.rest} "
                 f"{cloth.count}")
    print(f"mean |strain| %: before the limit {cloth.strain(x0):.2f}; colours "
          f"{cloth.colours().max() + 1}")
    if args.limited:
        limited = cloth.strain(read_frames(args.limited, args.frames))
        print(f"the kernel, {ITERATIONS} iterations {limited:.2f}; this reimplementation "
              f"{cloth.strain(cloth.chebyshev(x0, ITERATIONS)):.2f}")
    print("| iterations | Chebyshev (0.98, from 2): the kernel's | (0.98, from 5) | (0.97, from 2) "
          "| Gauss-Seidel 1.0 | SOR 1.5 | SOR 1.8 |")
    print("|---|---|---|---|---|---|---|")
    for n in (10, 15, 20, 30):
        cells = [cloth.chebyshev(x0, n), cloth.chebyshev(x0, n, start=5),
                 cloth.chebyshev(x0, n, 0.97, 2)] + [cloth.gauss_seidel(x0, n, w)
                                                      for w in (1.0, 1.5, 1.8)]
        print(f"| {n} | " + " | ".join(f"{cloth.strain(x):.2f}" for x in cells) + " |")


if __name__ == "__main__":
    main()
