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
