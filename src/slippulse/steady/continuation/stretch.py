"""Grid stretching: the predictor's stretched profile and the grid deformed with the pulse
(:func:`stretch_grid`, both edges kept, the body lengthened)."""
from __future__ import annotations

import numpy as np


def stretch_profile(xi, y, x0, s):
    """ln v stretched by the factor s about x0 behind it: y_new(ξ) = y(x0 + (ξ − x0)/s) for ξ < x0."""
    out = y.copy()
    behind = xi < x0
    out[behind] = np.interp(x0 + (xi[behind] - x0) / s, xi, y)
    return out


def _smoothstep(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def stretch_grid(xi, x0, shift, a, x_back, w):
    """Grid with the pulse body lengthened by `shift` and both edges kept.

    Parameters
    ----------
    xi : grid (ascending); x0 : the leading edge (the pin node); shift : how much longer the
    body gets (m); a : width of the leading-edge zone kept fixed; x_back, w : the healing front
    and the width of the zone about it moved rigidly.

    Notes
    -----
    With u = x0 − ξ (distance behind the front) and the weight
    φ(u) = S((u − a)/a) · [1 − S((u − u_b + 2w)/w)], u_b = x0 − x_back, S the C¹ smoothstep
    3t² − 2t³ on [0, 1], the nodes move to ξ − shift · G(u)/G(∞), G(u) = ∫_0^u φ. So the nodes within
    a of the front stay, the healing front (from u_b − w on) and the tail behind it are shifted
    rigidly by −shift, and only the body between is stretched: the structures whose widths do not
    grow with L keep their nodes (measured: stretching the healing front with the body lost its
    resolution and stopped the march at L ≈ 540 m, N = 2000). The map is smooth and, for
    shift > −G(∞), monotone; node count and order are kept.
    """
    xi = np.asarray(xi, float)
    u = x0 - xi
    ub = x0 - x_back
    phi = _smoothstep((u - a) / a) * (1.0 - _smoothstep((u - ub + 2.0 * w) / w))
    # G(u) on the nodes by the trapezoid rule, from the front (largest ξ) backward
    seg = 0.5 * (phi[1:] + phi[:-1]) * np.diff(xi)
    G = np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]])
    G -= G[np.searchsorted(xi, x0)]
    G = np.maximum(G, 0.0)
    return xi - shift * G / G[0]



def block_offset(xi, y, x_back, w):
    """How far the finest cells about the healing front lie from its steep drop (m).

    Within ``x_back ± w`` (the zone :func:`stretch_grid` moves rigidly; ``x_back`` the back
    half-maximum crossing), the centre of the grid's refinement, the mean of the cell midpoints
    weighted by 1/h², minus the centre of the drop, weighted by |Δ ln v| per cell. Positive: the
    fine cells lie ahead of the drop (toward the leading edge).

    Each deformed step moves the zone by the predicted change of L; the corrector then moves the
    front by what the prediction missed, so the drop wanders off the cells laid out for it
    (measured on the march from 2.5 to 9.5 km: the 0.05–0.1 m cells of the zone moved 0.6 m ahead of
    the back crossing per 100 m of L, 6 m at 4.8 km, 17 m at 6.8 km; the drop then sat on cells of
    0.15–0.31 m behind them, and the check found the healing front's error, docs/steady.md §8).
    """
    xi = np.asarray(xi, float)
    y = np.asarray(y, float)
    h = np.diff(xi)
    mid = 0.5 * (xi[1:] + xi[:-1])
    zone = (mid > x_back - w) & (mid < x_back + w)
    if not zone.any() or h[zone].max() < 1.5 * h[zone].min():
        return 0.0                      # no refinement there to move
    wh = 1.0 / h[zone] ** 2
    wd = np.abs(np.diff(y))[zone]
    if not wd.sum() > 0:
        return 0.0
    return float(np.sum(mid[zone] * wh) / wh.sum() - np.sum(mid[zone] * wd) / wd.sum())
