"""Principal-value Hilbert operator on a non-uniform grid, as a dense matrix.

    (H u)_i = PV ∫ u(z) / (z − ξ_i) dz

for the piecewise-cubic (natural spline) or piecewise-linear interpolant of the nodal values u_j,
integrated analytically segment by segment. Beyond the grid ends the field is continued by the
algebraic far-field tails u(z) = u_end (ξ_end − c)/(z − c) (the 1/ξ decay of a slip-rate excess
under a Hilbert-type stress), which keeps the PV finite at the end nodes and makes the far field
consistent; ``tails=False`` drops them (field zero outside).

Derivation (docs/steady.md §2): on segment j, s = (z − ξ_j)/h_j ∈ [0, 1], the Hermite cubic
p(s) = u_j H00 + u_{j+1} H01 + h_j m_j H10 + h_j m_{j+1} H11 gives
∫_seg p(z)/(z−ξ_i) dz = Σ_k c_k M_k(x0), x0 = (ξ_i − ξ_j)/h_j, with the moments
M_0 = ln|ξ_{j+1}−ξ_i| − ln|ξ_j−ξ_i|, M_k = 1/k + x0 M_{k−1} for targets near the segment
(−1 ≤ x0 ≤ 2; the logarithm of a zero distance is set to 0: those terms cancel between the two
segments sharing the node, with equal coefficient u_i), and Gauss–Legendre quadrature (order chosen
from the distance for 1e-16 accuracy) elsewhere. The spline slopes m = T⁻¹ R u (tridiagonal T, R),
so H = A + B T⁻¹ R; B T⁻¹ is obtained with one banded solve, making the assembly O(N²).
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np
from numba import njit
from scipy.linalg import solve_banded

_GL = {n: np.polynomial.legendre.leggauss(n) for n in (3, 4, 6, 8, 10, 12)}
#: Gauss–Legendre rules of the near-pole cells (shared with the stability kernels): GL_N[k] nodes
#: GL_NODES[k, :GL_N[k]] on [0, 1] with weights GL_WEIGHTS[k, :GL_N[k]], used where the pole
#: distance r ≥ GL_RMIN[k].
GL_NODES = np.zeros((6, 12))
GL_WEIGHTS = np.zeros((6, 12))
GL_N = np.array([3, 4, 6, 8, 10, 12])
for _k, _n in enumerate(GL_N):
    GL_NODES[_k, :_n] = 0.5 * (_GL[_n][0] + 1.0)   # mapped to [0, 1]
    GL_WEIGHTS[_k, :_n] = 0.5 * _GL[_n][1]
# Quadrature order by r = |2 x0 − 1| (pole distance in half-lengths): error ~ ρ^(−2n), ρ = r + √(r²−1)
GL_RMIN = np.array([400.0, 80.0, 20.0, 8.0, 4.0, 3.0])


@njit(cache=True)
def _log_abs(d):
    return np.log(abs(d)) if d != 0.0 else 0.0


@njit(cache=True)
def _assemble(xi, cubic, A, B):
    """Fill A (value weights) and B (slope weights, already × h_j) for all targets i."""
    n = xi.size
    for i in range(n):
        xt = xi[i]
        for j in range(n - 1):
            h = xi[j + 1] - xi[j]
            x0 = (xt - xi[j]) / h
            r = abs(2.0 * x0 - 1.0)
            if r <= 3.0:
                m0 = _log_abs(xi[j + 1] - xt) - _log_abs(xi[j] - xt)
                m1 = 1.0 + x0 * m0
                m2 = 0.5 + x0 * m1
                m3 = 1.0 / 3.0 + x0 * m2
            else:
                q = 0
                for k in range(GL_N.size):
                    if r >= GL_RMIN[k]:
                        q = k
                        break
                m0 = 0.0
                m1 = 0.0
                m2 = 0.0
                m3 = 0.0
                for k in range(GL_N[q]):
                    s = GL_NODES[q, k]
                    wk = GL_WEIGHTS[q, k] / (s - x0)
                    m0 += wk
                    m1 += wk * s
                    m2 += wk * s * s
                    m3 += wk * s * s * s
            if cubic:
                # H00 = 2s³−3s²+1, H01 = −2s³+3s², H10 = s³−2s²+s, H11 = s³−s²
                A[i, j] += 2.0 * m3 - 3.0 * m2 + m0
                A[i, j + 1] += -2.0 * m3 + 3.0 * m2
                B[i, j] += h * (m3 - 2.0 * m2 + m1)
                B[i, j + 1] += h * (m3 - m2)
            else:
                A[i, j] += m0 - m1
                A[i, j + 1] += m1


def _spline_system(xi):
    """Natural cubic spline in slope form: T m = R u, T as banded (3, N), R as three diagonals."""
    n = xi.size
    h = np.diff(xi)
    ih = 1.0 / h
    T = np.zeros((3, n))
    # T rows: upper diagonal T[0, 1:], main T[1, :], lower T[2, :-1]
    T[1, 0] = 2.0 * ih[0]
    T[0, 1] = ih[0]
    T[1, -1] = 2.0 * ih[-1]
    T[2, -2] = ih[-1]
    T[1, 1:-1] = 2.0 * (ih[:-1] + ih[1:])
    T[0, 2:] = ih[1:]
    T[2, :-2] = ih[:-1]
    # R u: row 0: 3(u1−u0)/h0², row n−1: 3(u_{n−1}−u_{n−2})/h²,
    # interior: 3[(u_j − u_{j−1})/h_{j−1}² + (u_{j+1} − u_j)/h_j²]
    lo = np.zeros(n)   # coefficient of u_{j−1} in row j
    di = np.zeros(n)   # coefficient of u_j
    up = np.zeros(n)   # coefficient of u_{j+1}
    ih2 = 3.0 * ih * ih
    di[0] = -ih2[0]
    up[0] = ih2[0]
    lo[-1] = -ih2[-1]
    di[-1] = ih2[-1]
    lo[1:-1] = -ih2[:-1]
    di[1:-1] = ih2[:-1] - ih2[1:]
    up[1:-1] = ih2[1:]
    return T, (lo, di, up)


def add_times_slopes(out, B, xi, overwrite_b=False):
    """out += B S, S = T⁻¹ R the natural-spline slope matrix (slopes m = S u), in O(N²).

    X = B T⁻¹ row by row (xᵢ T = bᵢ: the Thomas recursion of Tᵀ, factored once; T is strictly
    diagonally dominant, twice over, so no pivoting is needed), then X R with R tridiagonal with
    rows (lo, di, up): (X R)[:, k] = X[:, k] di_k + X[:, k+1] lo_{k+1} + X[:, k−1] up_{k−1}; one
    compiled pass over each row while it is in cache (0.04 s against 0.5 s for the banded
    LAPACK solve and the numpy products at N = 3542). B may be
    complex; `overwrite_b` is accepted for the callers and has no effect. Returns out.
    """
    T, (lo, di, up) = _spline_system(xi)
    if np.iscomplexobj(B) and not np.iscomplexobj(out):
        raise TypeError("add_times_slopes: a complex B needs a complex out")
    a, cp, inv = _thomas_factors(T)
    _times_slopes_rows(out, np.ascontiguousarray(B), a, cp, inv, lo, di, up)
    return out


#: Rows of B swept together by :func:`_times_slopes_rows`: the Thomas recursion is a chain of
#: dependent multiply-adds along a row, and R independent chains keep the FPU busy (N = 3542:
#: 0.038 s with 8 rows against 0.089 s one row at a time).
SLOPE_ROWS = 8


@njit(cache=True, nogil=True)
def _times_slopes_rows(out, B, a, cp, inv, lo, di, up):
    """out[i] += (B[i] T⁻¹) R for each row i (see :func:`add_times_slopes`), SLOPE_ROWS rows at
    a time."""
    m, n = B.shape
    R = SLOPE_ROWS
    z = np.empty((n, R), B.dtype)
    for i0 in range(0, m, R):
        nr = min(R, m - i0)
        for r in range(nr):
            z[0, r] = B[i0 + r, 0] * inv[0]
        for k in range(1, n):
            ak = a[k]
            ik = inv[k]
            for r in range(nr):
                z[k, r] = (B[i0 + r, k] - ak * z[k - 1, r]) * ik
        for k in range(n - 2, -1, -1):
            ck = cp[k]
            for r in range(nr):
                z[k, r] -= ck * z[k + 1, r]
        for r in range(nr):
            o = out[i0 + r]
            o[0] += z[0, r] * di[0] + z[1, r] * lo[1]
            for k in range(1, n - 1):
                o[k] += z[k, r] * di[k] + z[k + 1, r] * lo[k + 1] + z[k - 1, r] * up[k - 1]
            o[n - 1] += z[n - 1, r] * di[n - 1] + z[n - 2, r] * up[n - 2]


@njit(cache=True)
def _thomas_factors(T):
    """(a, c′, 1/d′) of the Thomas recursion of Tᵀ (T in banded storage, see
    :func:`_spline_system`): sub-diagonal a_k = T_{k−1,k} = T[0, k], super-diagonal
    c_k = T_{k+1,k} = T[2, k]."""
    n = T.shape[1]
    a = np.zeros(n)
    a[1:] = T[0, 1:]
    cp = np.empty(n)
    inv = np.empty(n)
    inv[0] = 1.0 / T[1, 0]
    cp[0] = T[2, 0] * inv[0]
    for k in range(1, n):
        inv[k] = 1.0 / (T[1, k] - a[k] * cp[k - 1])
        cp[k] = (T[2, k] * inv[k]) if k < n - 1 else 0.0
    return a, cp, inv


def spline_slopes(xi, u):
    """Slopes of the natural cubic spline through (ξ, u) (used by tests and interpolation)."""
    T, (lo, di, up) = _spline_system(np.asarray(xi, float))
    ru = di * u
    ru[1:] += lo[1:] * u[:-1]
    ru[:-1] += up[:-1] * u[1:]
    return solve_banded((1, 1), T, ru)


def tail_columns(xi, center):
    """Integrals of the far-field tails u_end (ξ_end − c)/(z − c) against 1/(z − ξ_i).

    Ahead (z > ξ_N, c < ξ_N): ∫_{ξ_N}^∞ a/((z−c)(z−ξ_i)) dz = a ln(|ξ_N−ξ_i|/|ξ_N−c|)/(c−ξ_i) with
    a = ξ_N − c; behind (z < ξ_1, c > ξ_1) symmetrically. At ξ_i = c the limits are a/(ξ_end − c).
    The ln of a zero distance (target at the end node) is set to 0 as in the interior segments.
    """
    xN, x1 = xi[-1], xi[0]
    aN, a1 = xN - center, center - x1
    d = center - xi
    with np.errstate(divide="ignore", invalid="ignore"):
        lnN = np.where(xi == xN, 0.0, np.log(np.abs(xN - np.where(xi == xN, 0.0, xi)))) \
            - np.log(abs(aN))
        ahead = aN * lnN / d
        ln1 = np.where(xi == x1, 0.0, np.log(np.abs(np.where(xi == x1, 0.0, xi) - x1))) \
            - np.log(abs(a1))
        behind = a1 * ln1 / d
    at_c = d == 0.0
    ahead[at_c] = aN / (xN - center)
    behind[at_c] = -a1 / (center - x1)
    # a target at the end node with ln(0) → 0 keeps the term consistent with the adjacent segment
    return behind, ahead


def hilbert_matrix(xi, kind: str = "cubic", tails: bool = True, center: float | None = None):
    """Dense matrix H with (H u)_i = PV∫ u(z)/(z − ξ_i) dz for the interpolant of u on the grid ξ.

    Parameters
    ----------
    xi : (N,) array, strictly ascending, m.
    kind : {"cubic", "linear", "fft"}
        Natural cubic spline (default), piecewise-linear interpolant, or the FFT spectral transform
        (uniform grids only, zero-padded ×2: :func:`hilbert_matrix_fft`).
    tails : bool
        Continue u beyond the ends with the algebraic far-field tails (see module notes).
    center : float, optional
        Centre c of the tails 1/(z − c); default: middle of the grid.

    Returns
    -------
    H : (N, N) ndarray, 1 (dimensionless: the integral of u has the units of u).
    """
    if kind == "fft":
        return hilbert_matrix_fft(xi, pad=2, tails=tails, center=center)
    xi = np.ascontiguousarray(xi, dtype=float)
    n = xi.size
    if n < 4 or np.any(np.diff(xi) <= 0):
        raise ValueError("hilbert_matrix needs ≥ 4 strictly ascending points")
    if kind not in HILBERT_KINDS:
        raise ValueError(f"kind={kind!r}: must be one of {sorted(HILBERT_KINDS)}")
    c = 0.5 * (xi[0] + xi[-1]) if center is None else float(center)     # as _add_tails
    key = (xi.tobytes(), kind, bool(tails), c)
    H = _CACHE.get(key)
    if H is not None:
        _CACHE.move_to_end(key)
        return H
    H = _hilbert_matrix(xi, kind, tails, center)
    H.flags.writeable = False
    _CACHE[key] = H
    while len(_CACHE) > 1 and sum(m.nbytes for m in _CACHE.values()) > CACHE_BYTES:
        _CACHE.popitem(last=False)
    return H


#: The latest matrices of :func:`hilbert_matrix`, by their arguments, returned (read-only) when
#: the same grid comes again, least recently used dropped first beyond :data:`CACHE_BYTES` (the
#: last one always kept). The spectrum's ladder solves the steady pulse on a mapped grid and
#: then builds the stability operator on the same grid (0.9 s at N = 5009); a family keeps
#: its grid for several pulses, and each pulse's grid check (the nested 2N − 1 grid) and test
#: functions (its own grid) come back to the same two grids: 145 assemblies for the 57 pulses of
#: the shallow family with one matrix kept, 60 with this cache (29 grids).
_CACHE = OrderedDict()
#: The most bytes :data:`_CACHE` keeps beyond its last matrix (four 2N − 1 = 2499 matrices).
CACHE_BYTES = 256 * 2 ** 20


def _hilbert_matrix(xi, kind, tails, center):
    """:func:`hilbert_matrix` itself (cubic or linear), built."""
    n = xi.size
    A = np.zeros((n, n))
    B = np.zeros((n, n))
    cubic = kind == "cubic"
    _assemble(xi, cubic, A, B)
    H = A
    if cubic:
        add_times_slopes(H, B, xi, overwrite_b=True)
    if tails:
        _add_tails(H, xi, center)
    return H


def _add_tails(H, xi, center):
    """Add the far-field tail integrals (see :func:`tail_columns`) to the end columns of H."""
    c = 0.5 * (xi[0] + xi[-1]) if center is None else float(center)
    if not (xi[0] < c < xi[-1]):
        raise ValueError("tail centre must lie inside the grid")
    behind, ahead = tail_columns(xi, c)
    H[:, 0] += behind
    H[:, -1] += ahead


HILBERT_KINDS = {"cubic": "natural cubic spline", "linear": "piecewise linear"}


# --------------------------------------------------------------------------------------------
# FFT-based alternative on a uniform grid (benchmarks/bench_steady_methods.py compares it).
def hilbert_matrix_fft(xi, pad: int | None = 2, tails: bool = False, center: float | None = None):
    """Dense matrix of the FFT (spectral) Hilbert transform on a UNIFORM grid.

    (H u)_i ≈ PV∫ u(z)/(z − ξ_i) dz for the band-limited (trigonometric) interpolant of u.

    Derivation: with û(k) = ∫ u e^{−ikx} dx, the transform of PV 1/x is −iπ sign(k); the operator
    u ↦ PV∫ u(z)/(z − ξ) dz = −(u * PV 1/x)(ξ) therefore has the symbol +iπ sign(k) (dimensionless,
    so no factor h). The nodal values are zero-padded to M = pad·N points and transformed with the
    discrete symbol iπ sign(k_m) (Nyquist mode set to 0); the operator is the circulant
    c = ifft(iπ sign(k)) restricted to the N×N block, H_ij = c[(i − j) mod M] (Toeplitz).
    On the periodic domain of length M h the kernel is the cotangent kernel
    c_k = −(π/M)(1 − (−1)^k) cot(π k/M); in the limit M → ∞ it becomes the lattice kernel of the
    sinc interpolant, c_k = −2/k for odd k, 0 for even k. Zero-padding by `pad` therefore leaves a
    wrap-around error of relative size ≈ (π k/M)²/3 on the entry |i − j| = k, up to ~(π/pad)²/3 on
    the far entries (k ~ N): the periodic images of the field are still felt. ``pad=None`` returns
    the M → ∞ lattice kernel itself (no wrap-around; what an infinitely padded FFT converges to).

    tails : add the same algebraic far-field continuation as :func:`hilbert_matrix` (the field
        beyond the ends ∝ 1/(z − c)); default False (field zero outside the grid).
    Raises ValueError when the grid is not uniform (relative spacing variation > 1e-8).
    """
    from scipy.linalg import toeplitz
    xi = np.ascontiguousarray(xi, dtype=float)
    n = xi.size
    if n < 4:
        raise ValueError("hilbert_matrix_fft needs ≥ 4 points")
    h = np.diff(xi)
    hm = (xi[-1] - xi[0]) / (n - 1)
    if hm <= 0 or np.max(np.abs(h - hm)) > 1e-8 * hm:
        raise ValueError("hilbert_matrix_fft needs a uniform, ascending grid")
    if pad is None:
        k = np.arange(1, n)
        col = np.concatenate([[0.0], np.where(k % 2 == 1, -2.0 / k, 0.0)])
        row = -col
    else:
        if int(pad) < 1:
            raise ValueError("pad must be ≥ 1")
        m = int(pad) * n
        m += m % 2
        sym = 1j * np.pi * np.sign(np.fft.fftfreq(m))
        sym[m // 2] = 0.0                                    # Nyquist mode: no sign
        c = np.fft.ifft(sym).real
        col = c[:n]                                          # H[i, 0] = c[i]
        row = c[(-np.arange(n)) % m]                         # H[0, j] = c[−j mod M]
    H = toeplitz(col, row)
    if tails:
        _add_tails(H, xi, center)
    return H


HILBERT_KINDS["fft"] = "FFT spectral transform on a uniform grid (zero-padded ×2)"
