# SPDX-License-Identifier: Apache-2.0
"""Smooth one-dimensional curves (numpy only): easing and cubic Hermite splines."""
import numpy as np


def ease(x):
    """0 below 0, 1 above 1, a C1 cubic in between (zero slope at both ends)."""
    t = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def ramp(x, start, end):
    """ease() of x mapped from [start, end] to [0, 1]."""
    return ease((np.asarray(x, dtype=float) - start) / (end - start))


def _slopes(xs, ys, flat_ends, monotone):
    """Knot tangents (n, d): a weighted mean of the two neighbouring secant slopes; with
    monotone, zero at a local extremum and shortened so the curve never overshoots its keys."""
    n = len(xs)
    h = np.diff(xs)[:, None]
    secant = np.diff(ys, axis=0) / h
    m = np.zeros_like(ys)
    if n > 2:
        w_left, w_right = h[1:], h[:-1]   # the nearer neighbour gets the larger weight
        m[1:-1] = (w_left * secant[:-1] + w_right * secant[1:]) / (w_left + w_right)
    if not flat_ends:
        m[0], m[-1] = secant[0], secant[-1]
    if monotone:
        if n > 2:
            same = secant[:-1] * secant[1:] > 0.0
            m[1:-1] = np.where(same, m[1:-1], 0.0)
        for i in range(n - 1):   # keep each interval's tangents within 3x its secant
            s = secant[i]
            safe = np.where(s == 0.0, 1.0, s)
            a = np.where(s == 0.0, 0.0, m[i] / safe)
            b = np.where(s == 0.0, 0.0, m[i + 1] / safe)
            r = np.hypot(a, b)
            k = np.where(r > 3.0, 3.0 / np.maximum(r, 1e-300), 1.0)
            m[i] = np.where(s == 0.0, 0.0, m[i] * k)
            m[i + 1] = np.where(s == 0.0, 0.0, m[i + 1] * k)
    return m


def hermite(xs, ys, x, flat_ends=True, monotone=True):
    """Cubic Hermite spline through the knots (xs increasing, ys (n,) or (n, d)) at x.

    Held constant outside [xs[0], xs[-1]]. flat_ends: zero slope at the first and last knot
    (motion keys starting and ending at rest); otherwise the end secants."""
    xs = np.asarray(xs, dtype=float)
    ys = np.asarray(ys, dtype=float)
    x = np.asarray(x, dtype=float)
    vector = ys.ndim == 2
    Y = ys if vector else ys[:, None]
    if len(xs) == 1:
        out = np.broadcast_to(Y[0], x.shape + (Y.shape[1],)).copy()
        return out if vector else out[..., 0]
    m = _slopes(xs, Y, flat_ends, monotone)
    i = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2)
    h = (xs[i + 1] - xs[i])[..., None]
    t = np.clip((x - xs[i]) / (xs[i + 1] - xs[i]), 0.0, 1.0)[..., None]
    out = ((1 + 2 * t) * (1 - t) ** 2 * Y[i] + t * (1 - t) ** 2 * h * m[i]
           + t * t * (3 - 2 * t) * Y[i + 1] + t * t * (t - 1) * h * m[i + 1])
    return out if vector else out[..., 0]


def profile(pairs):
    """A smooth function through (position, value) pairs (any order), for shape profiles."""
    pairs = sorted(pairs)
    xs = [p[0] for p in pairs]
    ys = [p[1] for p in pairs]
    return lambda q: hermite(xs, ys, q, flat_ends=False, monotone=True)


def even_by_length(points_of, count, closed, samples=4096):
    """Parameters in [0, 1] of `count` points spread evenly along the curve points_of(u)
    (u in [0, 1] -> (k, dims)). closed: at lengths i/count of the loop; open: the interior
    points at lengths i/(count + 1)."""
    u = np.linspace(0.0, 1.0, samples + 1)
    P = points_of(u)
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    if closed:
        at = np.arange(count) / count
    else:
        at = np.arange(1, count + 1) / (count + 1)
    return np.interp(at * length[-1], length, u)
