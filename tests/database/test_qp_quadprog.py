#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Blend weights of SimplexLeastSquares against quadprog (PyPI), for database sizes the C++
enumeration test cannot reach: k in {16, 30, 64} shapes, up to 3,000 rows, 300+ problems,
including rank-deficient databases (k > n, low rank, duplicate shapes) and shapes 1000 units
from the origin.

    minimise |A w - b|^2   subject to   sum(w) = 1,  0 <= w <= 1

The problems are made here with numpy and solved twice: by qp_solve_tool (the C++ solver, one
process for all problems) and by quadprog.solve_qp in w directly, which is independent of the
C++ solver's elimination of the sum (w = 1/k + Z y) and of its QR factor.

quadprog needs a strictly positive definite G, and A^T A is singular for rank-deficient
databases. So it gets G = D^T D + delta I with D = A - b 1^T (equal to |A w - b|^2 for
sum(w) = 1, and free of the large common offset that would ruin A^T A) and
delta = 1e-12 trace(D^T D) / k, scaled to trace 1 (quadprog's own tests are absolute). Its
answer meets the constraints only to about 1e-9, so it is clipped to [0, 1] and divided by its
sum: w_q is then feasible, f(w_q) >= f*, and w_q overshoots the true optimum f* by at most
delta (|w*|^2 - |w_q|^2) <= delta (|w|^2 <= 1 on the simplex) plus the effect of that clean-up.
Both solutions are scored with the same plain evaluation f(w) = |A w - b|^2, and the checks are

    f(w_ours) <= f(w_q) + tol                 ours is as good as quadprog's
    f(w_q)    <= f(w_ours) + tol + delta      quadprog's is not far above ours (a check of the
                                              reference; ours is feasible, so f(w_ours) >= f*)
    |reported objective - f(w_ours)| <= tol   the objective the C++ solver reports is right

with tol = kQpObjectiveRelTol |b|^2 (tests/support/test_support.h), and |sum w - 1| and the
bound violations within kQpConstraintTol.

Run by CTest (tests/database/CMakeLists.txt) with the interpreter made by scripts/setup.sh:
    python test_qp_quadprog.py --tool path/to/qp_solve_tool [--seed N]
DS_SEED=N overrides the seed too.
"""

import argparse
import os
import struct
import subprocess
import sys
import tempfile
import time

try:
    import numpy as np
    import quadprog
except ImportError as error:
    print(f"test_qp_quadprog: cannot import {error.name}: run scripts/setup.sh to create "
          f".venv with numpy and quadprog (scripts/requirements.txt)", file=sys.stderr)
    sys.exit(1)

# Mirrors tests/support/test_support.h (tolerances are stated there once).
QP_OBJECTIVE_REL_TOL = 1e-9
QP_CONSTRAINT_TOL = 1e-12
QUADPROG_RIDGE = 1e-12
DEFAULT_SEED = 20081112


# ---- Problems ----

def simplex_point(rng, k, sparse):
    w = rng.exponential(size=k)
    if sparse:
        w[rng.random(k) < 0.7] = 0.0
        if w.sum() == 0.0:
            w[rng.integers(k)] = 1.0
    return w / w.sum()


def targets(rng, A, count):
    """Poses for database A: inside the hull, near it, random, far outside, equal to a shape."""
    n, k = A.shape
    mean = A.mean(axis=1)
    spread = max(np.linalg.norm(A - mean[:, None]) / np.sqrt(n * k), 1e-3)
    out = []
    for i in range(count):
        kind = i % 5
        inside = A @ simplex_point(rng, k, sparse=rng.random() < 0.5)
        if kind == 0:
            out.append(inside)
        elif kind == 1:
            out.append(inside + rng.normal(scale=0.3 * spread, size=n))
        elif kind == 2:
            out.append(mean + rng.normal(scale=2.0 * spread, size=n))
        elif kind == 3:
            out.append(inside + rng.normal(scale=100.0 * spread, size=n))
        else:
            out.append(A[:, rng.integers(k)].copy())
    return np.stack(out, axis=1)


def world_shapes(rng, vertices, k):
    """Shapes like a posed mesh: a rest shape 1000 units from the origin plus a few smooth,
    pose-driven deformations (so the database is nearly low rank, as real ones are)."""
    rest = rng.normal(scale=0.3, size=(vertices, 3)) + np.array([1000.0, -650.0, 420.0])
    modes = rng.normal(size=(6, vertices, 3)) * np.linspace(0.05, 0.3, vertices)[None, :, None]
    coefficients = rng.normal(size=(k, 6))
    shapes = rest[None] + np.einsum("km,mvc->kvc", coefficients, modes)
    return shapes.reshape(k, 3 * vertices).T.copy()


def make_databases(rng):
    databases = []  # (category, A, B)
    frames = 12
    for k in (16, 30, 64):
        for n in (90, 3000):
            A = rng.normal(size=(n, k))
            databases.append(("random", A, targets(rng, A, frames)))
        n = 3 * (k // 6)  # fewer rows than shapes
        A = rng.normal(size=(n, k))
        databases.append(("k > n", A, targets(rng, A, frames)))
        for n in (300, 1500):
            A = rng.normal(size=(n, 5)) @ rng.normal(size=(5, k))  # rank 5
            databases.append(("low rank", A, targets(rng, A, frames)))
        for n in (120, 900):
            A = rng.normal(size=(n, k))
            for _ in range(k // 4):
                to = rng.integers(1, k)
                A[:, to] = A[:, rng.integers(0, to)]
            databases.append(("duplicates", A, targets(rng, A, frames)))
        for vertices in (40, 1000):
            A = world_shapes(rng, vertices, k)
            if vertices == 40:
                A[:, k - 1] = A[:, 0]
            databases.append(("offset 1000", A, targets(rng, A, frames)))
    return databases


# ---- qp_solve_tool ----

def write_input(path, databases):
    with open(path, "wb") as f:
        f.write(b"DSQPIN01")
        f.write(struct.pack("<i", len(databases)))
        for _, A, B in databases:
            n, k = A.shape
            f.write(struct.pack("<iii", n, k, B.shape[1]))
            f.write(np.asfortranarray(A, dtype="<f8").tobytes(order="F"))
            f.write(np.asfortranarray(B, dtype="<f8").tobytes(order="F"))


def read_output(path):
    data = open(path, "rb").read()
    if data[:8] != b"DSQPOUT1":
        raise RuntimeError(f"{path}: not a qp_solve_tool output")
    (count,) = struct.unpack_from("<i", data, 8)
    offset = 12
    results = []
    for _ in range(count):
        k, status, iterations = struct.unpack_from("<iii", data, offset)
        offset += 12
        values = np.frombuffer(data, dtype="<f8", count=5 + k, offset=offset)
        offset += 8 * (5 + k)
        results.append({
            "status": status, "iterations": iterations, "objective": values[0],
            "relativeResidual": values[1], "kktResidual": values[2], "sumError": values[3],
            "boundViolation": values[4], "weights": values[5:].copy()})
    if offset != len(data):
        raise RuntimeError(f"{path}: {len(data) - offset} trailing bytes")
    return results


# ---- Reference ----

def quadprog_weights(A, b):
    """Returns (w_q, delta): quadprog's minimiser of |D w|^2 + delta |w|^2 on the simplex,
    made exactly feasible."""
    k = A.shape[1]
    D = A - b[:, None]
    G = D.T @ D
    delta = QUADPROG_RIDGE * max(np.trace(G), np.finfo(float).tiny) / k
    G[np.diag_indices(k)] += delta
    # quadprog's tests are absolute (its infeasibility test fails on G of size 1e9), so G goes
    # in scaled to trace 1; the minimiser is the same.
    G /= np.trace(G)
    C = np.hstack([np.ones((k, 1)), np.eye(k), -np.eye(k)])
    bounds = np.concatenate([[1.0], np.zeros(k), -np.ones(k)])
    w = quadprog.solve_qp(G, np.zeros(k), C, bounds, meq=1)[0]
    # quadprog's answer misses the constraints by up to about 1e-9 (its sum and bounds are
    # met only to its own tolerances), which can score it below the true optimum; clipping to
    # [0, 1] and dividing by the sum makes it feasible, so that f(w_q) >= f* holds.
    w = np.clip(w, 0.0, 1.0)
    return w / w.sum(), delta


def objective(A, b, w):
    return float(np.sum((A @ w - b) ** 2))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tool", required=True, help="path to qp_solve_tool")
    parser.add_argument("--verbose", action="store_true", help="print every comparison")
    parser.add_argument("--seed", type=int,
                        default=int(os.environ.get("DS_SEED", DEFAULT_SEED)))
    args = parser.parse_args()
    print(f"[ seed     ] {args.seed} (override with DS_SEED=N or --seed N)")
    if not os.path.isfile(args.tool):
        print(f"test_qp_quadprog: {args.tool}: no such program (build qp_solve_tool)",
              file=sys.stderr)
        return 1

    rng = np.random.default_rng(args.seed)
    databases = make_databases(rng)
    with tempfile.TemporaryDirectory(prefix="ds-qp-") as folder:
        problems_path = os.path.join(folder, "problems.bin")
        weights_path = os.path.join(folder, "weights.bin")
        write_input(problems_path, databases)
        started = time.perf_counter()
        run = subprocess.run([args.tool, problems_path, weights_path], capture_output=True,
                             text=True)
        tool_seconds = time.perf_counter() - started
        if run.stderr:
            print(run.stderr, file=sys.stderr, end="")
        if run.returncode != 0:
            print(f"test_qp_quadprog: qp_solve_tool exited with {run.returncode}",
                  file=sys.stderr)
            return 1
        results = read_output(weights_path)

    failures = []
    worst = {"ours worse": 0.0, "|ours - quadprog|": 0.0, "reported": 0.0, "sum": 0.0,
             "bounds": 0.0, "kkt": 0.0, "ridge allowance": 0.0}
    counts = {}
    index = 0
    started = time.perf_counter()
    for category, A, B in databases:
        n, k = A.shape
        label = f"{category} (n = {n}, k = {k})"
        counts[label] = counts.get(label, 0) + B.shape[1]
        for f in range(B.shape[1]):
            b = B[:, f]
            result = results[index]
            index += 1
            where = f"problem {index - 1}: {label}, frame {f}"
            if result["status"] != 0:
                failures.append(f"{where}: qp_solve_tool status {result['status']}")
                continue
            w = result["weights"]
            w_q, delta = quadprog_weights(A, b)
            scale = max(float(b @ b), np.finfo(float).tiny)
            tol = QP_OBJECTIVE_REL_TOL * scale
            f_ours = objective(A, b, w)
            f_q = objective(A, b, w_q)
            ours_worse = (f_ours - f_q) / scale
            quadprog_better = (f_q - f_ours) / scale
            reported = abs(result["objective"] - f_ours) / scale
            sum_error = abs(w.sum() - 1.0)
            bound_error = max(0.0, -w.min(), w.max() - 1.0)
            if args.verbose:
                print(f"{where}: (f_ours - f_q) / |b|^2 = {ours_worse:.3g}, delta / |b|^2 = "
                      f"{delta / scale:.3g}, f_ours / |b|^2 = {f_ours / scale:.3g}")
            worst["ours worse"] = max(worst["ours worse"], ours_worse)
            worst["|ours - quadprog|"] = max(worst["|ours - quadprog|"], abs(ours_worse))
            worst["reported"] = max(worst["reported"], reported)
            worst["sum"] = max(worst["sum"], sum_error)
            worst["bounds"] = max(worst["bounds"], bound_error)
            worst["kkt"] = max(worst["kkt"], result["kktResidual"])
            worst["ridge allowance"] = max(worst["ridge allowance"], delta / scale)
            if f_ours > f_q + tol:
                failures.append(f"{where}: |Aw-b|^2 = {f_ours!r} but quadprog reaches {f_q!r} "
                                f"(|b|^2 = {scale!r}, tolerance {tol:.3g})")
            if f_q < f_ours - tol - delta:
                failures.append(f"{where}: quadprog's {f_q!r} is below ours {f_ours!r} by more "
                                f"than tolerance {tol:.3g} + ridge {delta:.3g}: is w feasible?")
            if reported > QP_OBJECTIVE_REL_TOL:
                failures.append(f"{where}: reported objective {result['objective']!r}, "
                                f"|Aw-b|^2 = {f_ours!r}")
            if sum_error > QP_CONSTRAINT_TOL or bound_error > QP_CONSTRAINT_TOL:
                failures.append(f"{where}: |sum w - 1| = {sum_error:.3g}, bound violation "
                                f"{bound_error:.3g} (tolerance {QP_CONSTRAINT_TOL:.3g})")
    reference_seconds = time.perf_counter() - started

    for label, count in counts.items():
        print(f"[ problems ] {label:<32} {count}")
    print(f"[ measured ] {index} problems; qp_solve_tool {tool_seconds:.2f} s, quadprog "
          f"{reference_seconds:.2f} s")
    print(f"[ measured ] worst (f_ours - f_quadprog) / |b|^2 = {worst['ours worse']:.3g}, worst "
          f"|f_ours - f_quadprog| / |b|^2 = {worst['|ours - quadprog|']:.3g}, worst "
          f"|reported - f_ours| / |b|^2 = {worst['reported']:.3g} (tolerance "
          f"{QP_OBJECTIVE_REL_TOL:.3g}; quadprog ridge allowance up to "
          f"{worst['ridge allowance']:.3g})")
    print(f"[ measured ] worst |sum w - 1| = {worst['sum']:.3g}, worst bound violation = "
          f"{worst['bounds']:.3g} (tolerance {QP_CONSTRAINT_TOL:.3g}); worst relative KKT "
          f"residual {worst['kkt']:.3g}")
    if index < 300:
        failures.append(f"only {index} problems; 300 or more expected")
    if failures:
        for line in failures[:20]:
            print(f"FAILED: {line}", file=sys.stderr)
        print(f"FAILED: {len(failures)} check(s) failed (seed {args.seed})", file=sys.stderr)
        return 1
    print("PASSED")
    return 0


if __name__ == "__main__":
    sys.exit(main())
