"""The smallest singular values of a square matrix, and their right singular vectors: a dense SVD
for a small matrix, else ARPACK on M⁻¹M⁻ᵀ with an LU of M or a given solve. Shared by the
branch-point test functions (σ₁, σ₂ of the bordered matrix, :mod:`.bifurcation`) and the shapes
of the nearly singular modes (:mod:`.null_modes`)."""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla

#: Largest matrix whose singular values are taken by a full SVD; above, the smallest come from
#: ARPACK on M⁻¹M⁻ᵀ with the LU of M (same numbers to ~1e-10, far cheaper at N = 6614).
DENSE_SVD_MAX = 400


def smallest_singular_values(M, lu=None, k=2, solve=None, vectors=False):
    """The k smallest singular values of a square M, ascending (dense SVD for small M; else
    ARPACK on M⁻¹M⁻ᵀ with the LU of M, ``lu`` if given, or ``solve(r, trans)`` = M⁻¹ r
    (M⁻ᵀ r with trans=1) if given). With ``vectors``: (values, right singular vectors as
    columns)."""
    m = M.shape[0]
    if m <= DENSE_SVD_MAX:
        if not vectors:
            return np.sort(sla.svdvals(M, check_finite=False))[:k]
        _, s, vt = sla.svd(M, check_finite=False)
        return s[::-1][:k], vt[::-1][:k].T
    from scipy.sparse.linalg import LinearOperator, eigsh
    if solve is None:
        if lu is None:
            lu = sla.lu_factor(M, check_finite=False)

        def solve(r, trans=0):
            return sla.lu_solve(lu, r, trans=trans, check_finite=False)

    def mv(x):
        return solve(solve(np.ravel(x), 1))

    op = LinearOperator((m, m), matvec=mv, dtype=float)
    out = eigsh(op, k=k, which="LM", return_eigenvectors=vectors, tol=1e-10,
                v0=np.ones(m) / math.sqrt(m))
    lam, vec = out if vectors else (out, None)
    order = np.argsort(-np.abs(lam))
    sig = 1.0 / np.sqrt(np.abs(lam[order]))
    return (sig, vec[:, order]) if vectors else sig
