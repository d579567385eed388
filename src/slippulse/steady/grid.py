"""Non-uniform grids for steady pulses: dense where ln v and ln φ vary fast, geometric far away.

A grid is built from a target spacing h(ξ) known at sample points: h is first replaced by its
lower envelope of slope γ, h(ξ) ← min_s [h_s + γ |ξ − ξ_s|], so that neighbouring cells differ by at
most a factor ≈ 1 + γ (geometric grading in the far field), then nodes are placed by equidistributing
∫ dξ/h, scaled to the requested number of points.
"""
from __future__ import annotations

import numpy as np


def envelope(xs, hs, gamma):
    """Lower envelope min_s [h_s + γ |ξ − ξ_s|] evaluated at the sorted sample points xs."""
    h = np.array(hs, dtype=float)
    for k in range(1, h.size):
        h[k] = min(h[k], h[k - 1] + gamma * (xs[k] - xs[k - 1]))
    for k in range(h.size - 2, -1, -1):
        h[k] = min(h[k], h[k + 1] + gamma * (xs[k + 1] - xs[k]))
    return h


def equidistribute(xs, h, n):
    """n nodes from xs[0] to xs[-1] with spacing proportional to the piecewise-linear h(ξ)."""
    dx = np.diff(xs)
    # ∫ dξ/h over each sample interval, h linear: Δξ ln(h1/h0)/(h1 − h0)
    h0, h1 = h[:-1], h[1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        seg = np.where(np.abs(h1 - h0) > 1e-12 * h0, dx * np.log(h1 / h0) / (h1 - h0), dx / h0)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    targets = np.linspace(0.0, cum[-1], n)
    # invert piecewise: inside interval k, cum is monotone; linear inversion in the cumulative is
    # accurate enough for placement (the nodes are what they are; the solver works on them).
    xi = np.interp(targets, cum, xs)
    xi[0], xi[-1] = xs[0], xs[-1]
    return xi


def build_grid(xs, hs, n, gamma=0.08, lo=None, hi=None):
    """Grid of n points on [lo, hi] from target spacings hs at sample points xs.

    Parameters
    ----------
    xs, hs : sample positions (m) and desired local spacings (m); need not be sorted.
    n : number of nodes.
    gamma : maximal spacing growth per unit length (grading ratio ≈ 1 + γ).
    lo, hi : domain ends (default: the sample range); the envelope extends to them.

    Notes
    -----
    Between two samples a < b the envelope is the tent min(h_a + γ(ξ−a), h_b + γ(b−ξ)); its apex
    ξ* = (h_b − h_a + γ(a + b))/(2γ) is inserted so that the piecewise-linear h is exact.
    """
    order = np.argsort(xs)
    xs = np.asarray(xs, float)[order]
    hs = np.asarray(hs, float)[order]
    lo = xs[0] if lo is None else lo
    hi = xs[-1] if hi is None else hi
    keep = (xs > lo) & (xs < hi)
    big = hi - lo
    xs = np.concatenate([[lo], xs[keep], [hi]])
    hs = np.concatenate([[big], hs[keep], [big]])
    h = envelope(xs, hs, gamma)
    a, b, ha, hb = xs[:-1], xs[1:], h[:-1], h[1:]
    apex = (hb - ha + gamma * (a + b)) / (2.0 * gamma)
    inside = (apex > a) & (apex < b)
    xs_all = np.concatenate([xs, apex[inside]])
    h_all = np.concatenate([h, ha[inside] + gamma * (apex[inside] - a[inside])])
    order = np.argsort(xs_all)
    return equidistribute(xs_all[order], h_all[order], n)


#: Width, in cells, of the Gaussian that smooths the log-spacing of a :class:`GridMap`.
MAP_WIDTH = 3.0


class GridMap:
    """A smooth monotone map t ∈ [0, 1] → ξ whose spacing follows a given grid's, smoothed.

    Grids of any size n sampled from one map (``gmap(n)``: ξ at t = 0, 1/(n−1), …, 1) are a
    family whose discretisation errors fall as a power of n, with no spacing jumps: the
    ladder of the spectrum's error estimate (:mod:`slippulse.spectrum.refine`,
    docs/spectrum.md §4). Nested refinement (midpoints inserted) keeps the jumps of the
    adapted grid's spacing, ratios up to ≈ 1.2 between neighbouring cells, at every level; the
    leading eigenvalue near τ_min then converges erratically.

    Parameters
    ----------
    xi : ascending grid (m), at least 4 nodes.
    width : standard deviation, in cells of `xi`, of the Gaussian that smooths ln Δξ.
    sub : samples per cell of `xi` for the map's quadrature.

    Notes
    -----
    x(u), u ∈ [0, 1], is the cubic spline through (k/(N−1), ξ_k) (monotone cubic if that one is
    not monotone). Its log-slope ℓ(u) = ln x′(u), smoothed by the Gaussian, ℓ_s, is the log of
    the wanted spacing. The density g = x′ e^{−ℓ_s} (cells of the new grid per unit u, up to a
    constant) integrates to G(u), normalised to G(1) = 1, and the map is t ↦ x(G⁻¹(t)): the
    nodes stay where the original grid put its resolution (no drift of the fine regions), and
    the spacing of ``gmap(n)`` is ∝ e^{ℓ_s}, smooth on the scale of `width` cells. With width = 0
    the map reproduces the original grid at n = N.
    """

    def __init__(self, xi, width=MAP_WIDTH, sub=32):
        from scipy.interpolate import CubicSpline, PchipInterpolator
        from scipy.ndimage import gaussian_filter1d
        xi = np.asarray(xi, dtype=float)
        n = xi.size
        if n < 4 or not np.all(np.isfinite(xi)) or not np.all(np.diff(xi) > 0):
            raise ValueError("a grid map needs at least 4 strictly ascending finite nodes")
        if not (width >= 0 and np.isfinite(width)):
            raise ValueError(f"width={width!r} is invalid: must be >= 0 (cells)")
        u = np.linspace(0.0, 1.0, n)
        uf = np.linspace(0.0, 1.0, (n - 1) * int(sub) + 1)
        x_of_u = CubicSpline(u, xi)
        dx = x_of_u(uf, 1)
        if np.any(dx <= 0.0):
            x_of_u = PchipInterpolator(u, xi)
            dx = x_of_u(uf, 1)
            dx = np.maximum(dx, 1e-300)
        lnd = np.log(dx)
        lnd_s = gaussian_filter1d(lnd, width * sub, mode="nearest") if width > 0 else lnd
        g = np.exp(lnd - lnd_s)
        G = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(uf))])
        G /= G[-1]
        self._x_of_u = x_of_u
        self._u_of_G = PchipInterpolator(G, uf)
        self.lo, self.hi = float(xi[0]), float(xi[-1])
        self.n_source = n
        self.width = float(width)

    def __call__(self, n):
        """The grid of n ≥ 4 nodes sampled from the map (ends exactly at the source's ends)."""
        if int(n) < 4:
            raise ValueError(f"n={n!r} is invalid: a mapped grid needs at least 4 nodes")
        t = np.linspace(0.0, 1.0, int(n))
        x = self._x_of_u(np.clip(self._u_of_G(t), 0.0, 1.0))
        x[0], x[-1] = self.lo, self.hi
        if not np.all(np.diff(x) > 0):
            raise ValueError("the grid map is not monotone at this n")
        return x
