"""What the nearly singular directions of a pulse's fixed-τ_d Newton matrix move, and how far a
fold is from a branch point.

A fold is where one real eigenvalue of the pinned fixed-τ_d problem crosses zero, and its null
vector says which feature of the pulse turns there. On a pulse with humps behind its front the
candidates are a shift of the whole pulse (the front pin removes it), of the front hump alone, and
of the humps behind it relative to the front (their separation). The right singular vectors of
A = [F_u F_c] for its smallest singular values are compared, by the cosine of their ln v part,
with d ln v/dξ on the whole grid, ahead of the split between the front hump and the humps behind
it, and behind the split; a cosine near one names the shift.

At a fold the left null vector ψ of A is not orthogonal to ∂F/∂q (the fold is transversal); at a
branch point it is. :func:`transversality` gives that cosine, whose convergence in N tells a
fold from a branch point that a discretisation unfolds (docs/branches.md §1).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .singular import DENSE_SVD_MAX, smallest_singular_values

#: A singular vector whose ln v part has a cosine of at least this with one of the shifts is
#: named after it.
SHIFT_COS = 0.9
#: A maximum of ln(v/v* + 1) counts as a hump if it stands this fraction of the largest value
#: above the lowest value between it and the front hump.
HUMP_PROMINENCE = 0.01


@dataclass(frozen=True)
class NullMode:
    """One small singular value σ of A and the cosines of its right singular vector's ln v part
    with the shifts (NaN behind/ahead where the pulse has a single hump); ``speed_part``: the
    size of its (β-scaled) speed component."""
    sigma: float
    speed_part: float
    shift_whole: float
    shift_front: float
    shift_trailing: float

    @property
    def shape(self) -> str:
        """'trailing-hump shift', 'whole-pulse shift', 'front-hump shift' or 'other'."""
        for name, c in (("trailing-hump shift", self.shift_trailing),
                        ("whole-pulse shift", self.shift_whole),
                        ("front-hump shift", self.shift_front)):
            if c >= SHIFT_COS:
                return name
        return "other"

    def describe(self) -> str:
        cos = max((c for c in (self.shift_trailing, self.shift_whole, self.shift_front)
                   if math.isfinite(c)), default=math.nan)
        return f"sigma={self.sigma:.3e}: {self.shape} (cos {cos:.3f})"


def hump_split(xi, v, v_star) -> int | None:
    """Index of the lowest node of y = ln(v/v* + 1) between the front hump's maximum (the
    maximum at the largest ξ that reaches half of max y; the pulse travels toward +ξ) and the
    highest hump behind it; None where the pulse has one hump. A hump behind is a local maximum
    of y that stands :data:`HUMP_PROMINENCE` of max y above the lowest y between it and the front
    hump's maximum."""
    y = np.log(np.asarray(v, float) / v_star + 1.0)
    xi = np.asarray(xi, float)
    peaks = [i for i in range(1, y.size - 1) if y[i] > y[i - 1] and y[i] >= y[i + 1]]
    if y.size > 1 and y[-1] > y[-2]:
        peaks.append(y.size - 1)
    if not peaks:
        return None
    top = float(y.max())
    front = max((i for i in peaks if y[i] >= 0.5 * top), key=lambda i: xi[i])
    behind = []
    for i in peaks:
        if xi[i] >= xi[front]:
            continue
        lo, hi = sorted((i, front))
        low = int(lo + np.argmin(y[lo:hi + 1]))
        if y[i] - y[low] >= HUMP_PROMINENCE * top:
            behind.append((y[i], i, low))
    if not behind:
        return None
    _, _, low = max(behind)
    return low


def null_modes(A, xi, lnv, v_star, k=2, lu=None) -> list[NullMode]:
    """The k smallest singular values of A (unknowns: ln v at the nodes ``xi``, then the speed)
    with the shifts their right singular vectors are (:class:`NullMode`), ascending."""
    xi = np.asarray(xi, float)
    lnv = np.asarray(lnv, float)
    n = xi.size
    sig, vec = smallest_singular_values(np.asarray(A, float), lu, k, vectors=True)
    dy = np.gradient(lnv, xi)
    split = hump_split(xi, np.exp(lnv), v_star)

    def cos(u, w):
        nw = float(np.linalg.norm(w))
        return abs(float(u @ w)) / (float(np.linalg.norm(u)) * nw) if nw > 0 else math.nan

    out = []
    for j in range(len(sig)):
        u = vec[:n, j]
        front = trailing = math.nan
        if split is not None:
            behind, ahead = dy.copy(), dy.copy()
            behind[split:] = 0.0
            ahead[:split] = 0.0
            front, trailing = cos(u, ahead), cos(u, behind)
        out.append(NullMode(float(sig[j]), float(abs(vec[n:, j]).sum()), cos(u, dy), front,
                            trailing))
    return out


def transversality(J, scale=None, lu=None, iterations=4) -> float:
    """|cos(ψ, c)| for the extended Jacobian J = [A c] (n × (n+1), the parameter last, columns
    scaled by ``scale``), ψ the left singular vector of A's smallest singular value (inverse
    iteration with the LU of A; a dense SVD for small or exactly singular A). Zero at a branch
    point; at a fold a number that converges in N."""
    J = np.asarray(J, float)
    if scale is not None:
        J = J * np.asarray(scale, float)[None, :]
    n = J.shape[0]
    A, c = J[:, :n], J[:, n]
    psi = None
    if n > DENSE_SVD_MAX:
        if lu is None:
            lu = sla.lu_factor(A, check_finite=False)
        psi = np.random.default_rng(0).standard_normal(n)
        with np.errstate(all="ignore"):
            for _ in range(iterations):
                psi = sla.lu_solve(lu, psi, trans=1, check_finite=False)
                psi /= np.linalg.norm(psi)
    if psi is None or not np.all(np.isfinite(psi)):     # small, or exactly singular: the SVD
        psi = sla.svd(A, check_finite=False)[0][:, -1]
    nc = float(np.linalg.norm(c))
    return abs(float(psi @ c)) / nc if nc > 0 else math.nan
