"""Mode-III spectral boundary-integral (SBI) kernel and history convolutions.

Two identical half-spaces in antiplane shear, periodic interface of length λ, slip δ(x, t), slip rate
V = ∂δ/∂t. In Fourier space (wavenumber k, ω_k = |k| c_s) the interface stress is (docs/dynamic.md)

    τ_k(t) = τ_load,k − (μ/2c_s) V_k(t) + f_k(t),
    f_k(t) = −(μ|k|/2) [ δ_k(t) − H_k(t) ],     H_k(t) = ∫_0^t K(ω_k s) V_k(t − s) ds,
    K(T) = ∫_T^∞ J1(s)/s ds = 1 − ∫_0^T J0(s) ds + J1(T),

one convolution per mode. K(0) = 1, K(T) ~ T^{-3/2} oscillating, ∫_0^∞ K = 1.
Its integral P(T) = ∫_0^T K = T K(T) + 1 − J0(T) gives the step-integrated weights.

History policies (registry ``HISTORY_POLICIES``; all share ``begin_step``/``current``/``commit``):

``full``    every past interval kept; exact pre-integrated weights; fixed dt only. O(n) per mode.
``window``  per-mode window of ⌈T_w/(ω_k Δt)⌉ intervals (T_w = 2π·periods), capped, stored as
            per-mode rings in one flat array; fixed dt only.
``soe``     sum of exponentials K(T) ≈ Re Σ_j a_j e^{z_j T} from a quadrature of the branch-cut
            integral of K's Laplace transform; recursive update, O(p) per mode, any Δt.

Every policy treats the velocity over a step as constant, equal to the step average V̄ (the
predictor–corrector supplies V̄ = (V^n + V^{n+1})/2), which is second-order in Δt.
"""
from __future__ import annotations

import math

import numba
import numpy as np
from scipy import special

# ----------------------------------------------------------------------------- the kernel


def kernel_K(T):
    """Velocity-form mode-III kernel K(T) = ∫_T^∞ J1(s)/s ds (dimensionless, T = |k| c_s t ≥ 0).

    Notes
    -----
    Uses J1(s)/s = J0(s) − J1'(s), so ∫_0^T J1(s)/s ds = ∫_0^T J0 − J1(T) (``integral_j0``).
    Absolute accuracy ~1e-15.
    """
    T = np.asarray(T, dtype=float)
    return 1.0 - (integral_j0(T) - special.j1(T))


_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)
_T_SWITCH = 50.0


def _cumulative_j0_table():
    """∫_0^n J0 for n = 0..50 (16-point Gauss–Legendre per unit panel; error ~1e-16)."""
    lo = np.arange(int(_T_SWITCH))[:, None]
    panels = 0.5 * np.sum(_GL_W[None, :] * special.j0(lo + 0.5 * (_GL_X[None, :] + 1.0)), axis=1)
    return np.concatenate([[0.0], np.cumsum(panels)])


_J0_TABLE = _cumulative_j0_table()


def integral_j0(T):
    """∫_0^T J0(s) ds, accurate to ~1e-15 absolute for all T ≥ 0.

    T < 50: tabulated ∫_0^n J0 at the integer n = ⌊T⌋ plus 16-point Gauss–Legendre on [n, T].
    T ≥ 50: scipy ``itj0y0`` (its series/asymptotic switch near T = 20 errs by up to 5e-10, and
    scipy's Struve H0 returns NaN at isolated points such as 25.765364, hence the quadrature).
    """
    T = np.asarray(T, dtype=float)
    out = np.empty_like(T)
    flat_T, flat_out = T.reshape(-1), out.reshape(-1)
    small = flat_T < _T_SWITCH
    idx = np.nonzero(small)[0]
    for c in range(0, idx.size, 1 << 16):          # bounded temporaries
        i = idx[c:c + (1 << 16)]
        t = flat_T[i]
        n = np.floor(t)
        h = t - n
        nodes = n[:, None] + 0.5 * h[:, None] * (_GL_X[None, :] + 1.0)
        flat_out[i] = _J0_TABLE[n.astype(np.int64)] + 0.5 * h * (special.j0(nodes) @ _GL_W)
    big = ~small
    flat_out[big] = special.itj0y0(flat_T[big])[0]
    return out


def kernel_P(T):
    """P(T) = ∫_0^T K(u) du = T K(T) + 1 − J0(T); P(0) = 0, P(∞) = 1."""
    T = np.asarray(T, dtype=float)
    return T * kernel_K(T) + 1.0 - special.j0(T)


def step_weights(omega, dt, m0, m1, chunk=64):
    """Pre-integrated weights W[m, k] = ∫_{mΔt}^{(m+1)Δt} K(ω_k s) ds, for lags m0 ≤ m < m1, s.

    W = [P(ω(m+1)Δt) − P(ωmΔt)]/ω; for ω = 0 (mode k = 0) K ≡ 1 and W = Δt.
    Computed ``chunk`` lags at a time to bound the temporaries.
    """
    omega = np.asarray(omega, dtype=float)
    W = np.empty((m1 - m0, omega.size))
    zero = omega == 0.0
    safe = np.where(zero, 1.0, omega)
    for c0 in range(m0, m1, chunk):
        c1 = min(m1, c0 + chunk)
        m = np.arange(c0, c1 + 1, dtype=float)[:, None]
        Pm = kernel_P(m * dt * omega[None, :])
        W[c0 - m0:c1 - m0] = np.diff(Pm, axis=0) / safe[None, :]
    W[:, zero] = dt
    return W


def ragged_weights(omega, dt, nw):
    """Flattened per-mode weights: W_k[m], m = 0..nw[k], stored at offsets off[k] (returns W, off)."""
    omega = np.asarray(omega, dtype=float)
    nw = np.asarray(nw, dtype=np.int64)
    off = np.zeros(omega.size + 1, dtype=np.int64)
    np.cumsum(nw + 1, out=off[1:])
    W = np.empty(int(off[-1]))
    mmax = int(nw.max())
    for c0 in range(0, mmax + 1, 64):      # lag blocks: every mode whose window reaches c0
        c1 = min(mmax + 1, c0 + 64)
        ks = np.nonzero(nw >= c0)[0]
        blk = step_weights(omega[ks], dt, c0, c1)
        for j, k in enumerate(ks):
            hi = min(c1, int(nw[k]) + 1)
            W[off[k] + c0:off[k] + hi] = blk[:hi - c0, j]
    return W, off


def soe_nodes(x_min=1e-8, x_max=1e8, h=0.5):
    """Sum-of-exponentials approximation K(T) ≈ Re Σ_j a_j exp(z_j T), T ≥ 0.

    Returns
    -------
    z, a : complex arrays (p,)
        Exponents z_j = i − x_j (Re z_j < 0) and complex weights.

    Notes
    -----
    The Laplace transform of K is K̂(s) = (1 + s − √(1+s²))/s with √(1+s²) = √(s−i)√(s+i)
    (principal roots: cuts along s = ±i − x, x > 0). Deforming the Bromwich contour around the
    two cuts (the jump of √(1+s²) across the upper cut is 2i√x√(2i−x)) gives

        K(T) = (2/π) Re[ e^{iT} ∫_0^∞ ρ(x) e^{−xT} dx ],   ρ(x) = √x √(2i − x) / (i − x).

    The trapezoidal rule in u = ln x with step h on [ln x_min, ln x_max] gives the nodes:
    a_j = (2/π) h x_j ρ(x_j), z_j = i − x_j. The error decays like exp(−π²/h); x_max bounds the
    near-field error (it misses a mass ≈ (2/π)/x_max at T ≲ 1/x_max) and x_min the far tail
    (T ≳ 1/x_min). Defaults (75 nodes) reproduce P(T) = ∫_0^T K to ~1e-7 for T ≤ 1e6.
    """
    if not (0 < x_min < x_max) or h <= 0:
        raise ValueError("soe_nodes needs 0 < x_min < x_max and h > 0")
    u = np.arange(math.log(x_min), math.log(x_max) + 0.5 * h, h)
    x = np.exp(u)
    rho = np.sqrt(x) * np.sqrt(2j - x) / (1j - x)
    return 1j - x, (2.0 / math.pi) * h * x * rho


# ----------------------------------------------------------------------------- numba kernels

_BLOCK = 512


@numba.njit(parallel=True, cache=True)
def _ring_sum(hist, head, count, W, nw, out):
    """out[k] = Σ_{m=1}^{min(count, nw[k])} W[m, k] · hist[(head − m) mod cap, k]."""
    cap, nk = hist.shape
    nblocks = (nk + _BLOCK - 1) // _BLOCK
    for b in numba.prange(nblocks):
        k0 = b * _BLOCK
        k1 = min(nk, k0 + _BLOCK)
        mmax = 0
        for k in range(k0, k1):
            mk = min(count, nw[k])
            if mk > mmax:
                mmax = mk
        for k in range(k0, k1):
            out[k] = 0.0
        for m in range(1, mmax + 1):
            idx = (head - m) % cap
            for k in range(k0, k1):
                if m <= nw[k]:
                    out[k] += W[m, k] * hist[idx, k]


@numba.njit(parallel=True, cache=True)
def soe_past(E, Y, C, out):
    """out[k] = Re Σ_j C_j E_kj Y_kj0 + i Re Σ_j C_j E_kj Y_kj1: the history part of H_k."""
    nk, p, _ = Y.shape
    for k in numba.prange(nk):
        s1 = 0.0
        s2 = 0.0
        for j in range(p):
            ce = C[j] * E[k, j]
            s1 += (ce * Y[k, j, 0]).real
            s2 += (ce * Y[k, j, 1]).real
        out[k] = complex(s1, s2)


@numba.njit(parallel=True, cache=True)
def soe_commit(E, G, Y, V, C, past_next):
    """Y_kj ← E_kj Y_kj + G_kj (Re V̄_k, Im V̄_k) (exact for V constant over the step), and in the
    same pass the next step's history sum (``soe_past`` of the new Y) in case Δt is kept."""
    nk, p, _ = Y.shape
    for k in numba.prange(nk):
        u = V[k].real
        w = V[k].imag
        s1 = 0.0
        s2 = 0.0
        for j in range(p):
            e = E[k, j]
            g = G[k, j]
            y1 = e * Y[k, j, 0] + g * u
            y2 = e * Y[k, j, 1] + g * w
            Y[k, j, 0] = y1
            Y[k, j, 1] = y2
            ce = C[j] * e
            s1 += (ce * y1).real
            s2 += (ce * y2).real
        past_next[k] = complex(s1, s2)


# ----------------------------------------------------------------------------- policies


class HistoryPolicy:
    """Common interface of the history convolutions H_k(t) = ∫_0^t K(ω_k s) V_k(t − s) ds.

    Per step: ``begin_step(dt)`` sums the stored past (intervals before the current one) once;
    ``current(V̄)`` returns H_k at the end of the step for a trial step average V̄ (cheap: called
    by the predictor and the corrector); ``commit(V̄)`` appends the step.
    """

    name = "?"
    variable_dt = False

    def __init__(self, omega: np.ndarray):
        self.omega = np.asarray(omega, dtype=float)
        self.nk = self.omega.size
        self._past = np.zeros(self.nk, dtype=complex)
        self._w0 = np.zeros(self.nk)
        self._dt = None

    def _w0_for(self, dt):
        return step_weights(self.omega, dt, 0, 1)[0]

    def current(self, vbar_k: np.ndarray) -> np.ndarray:
        """H_k(t_{n+1}) for the step average V̄_k (the current interval uses the exact weight)."""
        return self._past + self._w0 * vbar_k

    # subclasses: begin_step, commit, state, load_state, nbytes


class _RingHistory(HistoryPolicy):
    """Fixed-Δt history of step averages in a ring buffer with exact pre-integrated weights."""

    def __init__(self, omega, dt, capacity, nw):
        super().__init__(omega)
        if dt is None or dt <= 0:
            raise ValueError(f"history policy '{self.name}' needs a fixed time step (got dt={dt})")
        self.dt = float(dt)
        self.nw = np.asarray(nw, dtype=np.int64)
        self.cap = int(capacity)
        self.hist = np.zeros((self.cap, self.nk), dtype=complex)
        self.head = 0
        self.count = 0
        self.W = step_weights(self.omega, self.dt, 0, min(self.cap, int(self.nw.max())) + 1)
        self._w0 = self.W[0].copy()

    def _check_dt(self, dt):
        if abs(dt - self.dt) > 1e-12 * self.dt:
            raise ValueError(f"history policy '{self.name}' needs a fixed time step: got dt={dt:.17g}, "
                             f"built for {self.dt:.17g}; use policy 'soe' for variable steps")

    def _ensure_weights(self, mmax):
        have = self.W.shape[0]
        if mmax < have:
            return
        new = max(mmax + 1, 2 * have)
        self.W = np.concatenate([self.W, step_weights(self.omega, self.dt, have, new)], axis=0)

    def begin_step(self, dt):
        self._check_dt(dt)
        self._ensure_weights(min(self.count, int(self.nw.max())))
        _ring_sum(self.hist, self.head, self.count, self.W, self.nw, self._past)

    def commit(self, vbar_k, dt):
        self.hist[self.head] = vbar_k
        self.head = (self.head + 1) % self.cap
        self.count += 1

    def chronological(self) -> np.ndarray:
        """Stored step averages, oldest first."""
        n = min(self.count, self.cap)
        idx = (self.head - n + np.arange(n)) % self.cap
        return self.hist[idx]

    def state(self) -> dict:
        return {"hist": self.chronological(), "count": np.int64(self.count)}

    def load_state(self, st: dict):
        h = np.asarray(st["hist"])
        self.count = int(st["count"])
        n = h.shape[0]
        if n > self.cap:
            self._grow(n)
        self.hist[:] = 0.0
        self.hist[:n] = h
        self.head = n % self.cap

    def _grow(self, need):
        raise ValueError("history buffer too small")

    @property
    def nbytes(self) -> int:
        return self.hist.nbytes + self.W.nbytes


class FullHistory(_RingHistory):
    """Every past step kept (buffer doubles when full). Exact up to the Δt discretisation."""

    name = "full"

    def __init__(self, omega, dt, initial_capacity=256, **_):
        big = np.iinfo(np.int64).max // 4
        super().__init__(omega, dt, initial_capacity, np.full(np.asarray(omega).size, big))

    def _grow(self, need):
        old = self.chronological()
        n = old.shape[0]
        self.cap = max(need, 2 * self.cap)
        self.hist = np.zeros((self.cap, self.nk), dtype=complex)
        self.hist[:n] = old
        self.head = n % self.cap

    def commit(self, vbar_k, dt):
        if self.count >= self.cap:
            self._grow(self.count + 1)
        super().commit(vbar_k, dt)


@numba.njit(parallel=True, cache=True)
def _ragged_sum(hist, W, off, hoff, nw, count, out):
    """out[k] = Σ_{m=1}^{min(count, nw[k])} W_k[m] · h_k[(count − m) mod nw[k]] (per-mode rings)."""
    nk = nw.size
    for k in numba.prange(nk):
        L = nw[k]
        s = 0j
        mk = min(count, L)
        base, wb = hoff[k], off[k]
        for m in range(1, mk + 1):
            s += W[wb + m] * hist[base + (count - m) % L]
        out[k] = s


@numba.njit(parallel=True, cache=True)
def _ragged_commit(hist, hoff, nw, count, v):
    for k in numba.prange(nw.size):
        L = nw[k]
        if L > 0:
            hist[hoff[k] + count % L] = v[k]


class WindowHistory(HistoryPolicy):
    """Truncated history (Lapusta et al. 2000 style): mode k keeps n_w(k) = min(max_steps,
    ⌈2π·periods/(ω_k Δt)⌉) steps (``periods`` kernel oscillation periods); older contributions
    are dropped. Each mode has its own ring of length n_w(k) in one flat array, so the memory is
    Σ_k n_w(k) (16 + 8) bytes — short for the many fast modes, long only for the few slow ones."""

    name = "window"

    def __init__(self, omega, dt, periods=4.0, max_steps=2000, **_):
        super().__init__(omega)
        if dt is None or dt <= 0:
            raise ValueError(f"history policy '{self.name}' needs a fixed time step (got dt={dt})")
        if periods <= 0 or max_steps < 1:
            raise ValueError("window policy needs periods > 0 and max_steps >= 1")
        self.dt = float(dt)
        self.periods, self.max_steps = periods, int(max_steps)
        with np.errstate(divide="ignore"):
            nw = np.ceil(2.0 * math.pi * periods / (self.omega * self.dt))
        # k = 0 carries no elastic stress (μ|k| = 0): no history
        self.nw = np.where(np.isfinite(nw), np.minimum(nw, self.max_steps), 0).astype(np.int64)
        self.W, self.off = ragged_weights(self.omega, self.dt, self.nw)
        self._w0 = self.W[self.off[:-1]].copy()
        self._w0[self.omega == 0.0] = self.dt
        self.hoff = np.zeros(self.nk + 1, dtype=np.int64)
        np.cumsum(self.nw, out=self.hoff[1:])
        self.hist = np.zeros(int(self.hoff[-1]), dtype=complex)
        self.count = 0

    def _check_dt(self, dt):
        if abs(dt - self.dt) > 1e-12 * self.dt:
            raise ValueError(f"history policy '{self.name}' needs a fixed time step: got dt={dt:.17g}, "
                             f"built for {self.dt:.17g}; use policy 'soe' for variable steps")

    def begin_step(self, dt):
        self._check_dt(dt)
        _ragged_sum(self.hist, self.W, self.off, self.hoff, self.nw, self.count, self._past)

    def commit(self, vbar_k, dt):
        _ragged_commit(self.hist, self.hoff, self.nw, self.count,
                       np.ascontiguousarray(vbar_k, dtype=complex))
        self.count += 1

    def state(self) -> dict:
        return {"hist": self.hist.copy(), "count": np.int64(self.count)}

    def load_state(self, st: dict):
        self.hist[:] = st["hist"]
        self.count = int(st["count"])

    @property
    def nbytes(self) -> int:
        return self.hist.nbytes + self.W.nbytes


def lru_lookup(cache: dict, key, size: int, make):
    """``cache[key]``, made by ``make()`` on a miss; the entry moves to the most recently used end
    (dicts keep insertion order) and the least recently used ones beyond ``size`` are dropped."""
    hit = cache.pop(key, None)
    if hit is None:
        hit = make()
    cache[key] = hit
    while len(cache) > size:
        cache.pop(next(iter(cache)))
    return hit


class SOEHistory(HistoryPolicy):
    """Sum-of-exponentials history. K(T) ≈ Re Σ_j a_j e^{z_j T} (``soe_nodes``) and K is real, so
    with V_k = u + i w (u, w real)

        H_k = Re Σ_j a_j Y⁽ᵘ⁾_jk + i Re Σ_j a_j Y⁽ʷ⁾_jk,   Y⁽ᵘ⁾_jk(t) = ∫_0^t e^{z_j ω_k s} u(t−s) ds,

    two complex accumulators per node and mode. Over a step of any length Δt at constant V̄ the
    update is exact: Y ← e^{z ω Δt} Y + (e^{z ω Δt} − 1)/(z ω) · (Re V̄, Im V̄).
    The current step uses the exact weight P(ωΔt)/ω. The step coefficients (e^{zωΔt},
    (e^{zωΔt} − 1)/(zω), P(ωΔt)/ω) of the last ``cache_size`` distinct Δt are kept (adaptive
    stepping picks Δt on a geometric ladder, so few distinct values occur).
    Memory: (N/2+1)·p·(32 + 32 per cached Δt) bytes.
    """

    name = "soe"
    variable_dt = True

    def __init__(self, omega, dt=None, x_min=1e-8, x_max=1e8, h=0.5, cache_size=3, **_):
        super().__init__(omega)
        z, a = soe_nodes(x_min, x_max, h)
        self.Z, self.C = z, a
        self.p = self.Z.size
        self.Y = np.zeros((self.nk, self.p, 2), dtype=complex)
        self.E = self.G = None
        self._past_next = np.zeros(self.nk, dtype=complex)
        self._next_dt = None
        self._cache = {}
        self.cache_size = int(cache_size)
        self.count = 0

    def _set_dt(self, dt):
        if self._dt == dt:
            return
        self._dt = dt
        self.E, self.G, self._w0 = lru_lookup(self._cache, dt, self.cache_size,
                                              lambda: self._factors(dt))

    def factors_at(self, dt):
        """(E, G, w0) of the step Δt = dt, made the current step's (cached): what a device copy
        of this history uploads."""
        self._set_dt(dt)
        return self.E, self.G, self._w0

    def _factors(self, dt):
        """(E, G, w0) of the step Δt = dt."""
        zw = self.Z[None, :] * self.omega[:, None] * dt
        E = np.exp(zw)
        with np.errstate(divide="ignore", invalid="ignore"):
            G = np.expm1(zw) / (self.Z[None, :] * self.omega[:, None])
        zero = self.omega == 0.0
        G[zero] = 0.0          # mode k = 0 carries no elastic stress (μ|k| = 0)
        E[zero] = 0.0
        E[np.abs(E) < 1e-250] = 0.0   # no subnormal arithmetic (100× slower); effect < 1e-250
        return E, G, self._w0_for(dt)

    def begin_step(self, dt):
        dt = float(dt)
        if self._next_dt == dt:                 # summed during the last commit (same Δt)
            self._past[:] = self._past_next
        else:
            self._set_dt(dt)
            soe_past(self.E, self.Y, self.C, self._past)

    def commit(self, vbar_k, dt):
        self._set_dt(float(dt))
        soe_commit(self.E, self.G, self.Y, np.ascontiguousarray(vbar_k, dtype=complex), self.C,
                    self._past_next)
        self._next_dt = float(dt)
        self.count += 1

    def prefill_translating(self, vhat_k, kabs, c, sigma=0.0, add=False):
        """History of a slip-rate field that has translated at speed c (toward +x) forever:
        V_k(t) = V̂_k e^{−ikct} for t ≤ 0, so Y_jk(0) = ∫_0^∞ e^{z_j ω_k s} V_k(−s) ds with
        ∫_0^∞ e^{zωs} e^{±ikcs} ds = −1/(zω ± ikc) (Re z < 0) for the real and imaginary parts.
        Mode k = 0 (no elastic stress) is left empty.

        ``sigma`` (real, ≥ 0, 1/s): the field also grew as e^{σt} in the past, V_k(t) =
        V̂_k e^{(σ − ikc)t} for t ≤ 0 (an unstable eigenmode, docs/stability.md §2); then
        ∫_0^∞ e^{zωs} e^{−σs} e^{±ikcs} ds = −1/(zω − σ ± ikc). ``add``: add this past to the
        accumulators (the perturbation over a steady past) instead of replacing them."""
        vhat = np.asarray(vhat_k, dtype=complex)[:, None]
        zw = self.Z[None, :] * self.omega[:, None] - float(sigma)
        kc = 1j * np.asarray(kabs, dtype=float)[:, None] * c
        with np.errstate(all="ignore"):
            plus = -vhat / (zw + kc)
            minus = -np.conj(vhat) / (zw - kc)
            yu, yw = 0.5 * (plus + minus), (plus - minus) / 2j
        zero = self.omega == 0.0
        yu[zero] = 0.0
        yw[zero] = 0.0
        if add:
            self.Y[:, :, 0] += yu
            self.Y[:, :, 1] += yw
        else:
            self.Y[:, :, 0] = yu
            self.Y[:, :, 1] = yw
        self._next_dt = None

    def shift(self, theta: np.ndarray) -> None:
        """Relabel the ring by a spatial shift: V_k ← V_k e^{iθ_k} for the whole past.

        The u and w accumulators hold the real and imaginary parts of V_k's past, so they rotate:
        (Y⁽ᵘ⁾, Y⁽ʷ⁾) ← (cos θ Y⁽ᵘ⁾ − sin θ Y⁽ʷ⁾, sin θ Y⁽ᵘ⁾ + cos θ Y⁽ʷ⁾). Exact (the convolution is
        linear and translation invariant); the pre-summed past of the next step is recomputed.
        """
        rotate_accumulators(self.Y, np.cos(theta), np.sin(theta))
        self._next_dt = None

    def value(self) -> np.ndarray:
        """H_k at the current time from the accumulators alone: Re Σ a Y⁽ᵘ⁾ + i Re Σ a Y⁽ʷ⁾."""
        aY = np.einsum("j,kjc->kc", self.C, self.Y)
        return aY[:, 0].real + 1j * aY[:, 1].real

    def state(self) -> dict:
        return {"Y": self.Y.copy(), "count": np.int64(self.count)}

    def load_state(self, st: dict):
        self.Y[:] = st["Y"]
        self.count = int(st["count"])
        self._dt = None
        self._next_dt = None

    @property
    def nbytes(self) -> int:
        return self.Y.nbytes + sum(e.nbytes + g.nbytes for e, g, _ in self._cache.values())


def rotate_accumulators(Y, cos_theta, sin_theta) -> None:
    """(Y⁽ᵘ⁾, Y⁽ʷ⁾) ← (cos θ Y⁽ᵘ⁾ − sin θ Y⁽ʷ⁾, sin θ Y⁽ᵘ⁾ + cos θ Y⁽ʷ⁾) in place, per mode k
    (Y[k, j, c]; numpy or CuPy arrays): the SOE accumulators under a spatial shift."""
    c = cos_theta[:, None]
    sn = sin_theta[:, None]
    yu = Y[:, :, 0].copy()
    yw = Y[:, :, 1]
    Y[:, :, 0] = c * yu - sn * yw
    Y[:, :, 1] = sn * yu + c * yw


class QuasiDynamicHistory(HistoryPolicy):
    """No elastodynamic memory at all: H_k ≡ 0, so f_k = −(μ|k|/2)δ_k is the *static* stress of
    the current slip and, with the stepper's radiation damping −ηV, the model is quasi-dynamic.

    Not a discretisation of the mode-III kernel: the quasi-dynamic model of the failure map
    (does a steady pulse of the full problem survive in it, and at what speed?). Any Δt; the
    translating past of a seeded pulse is simply absent (``prefill_translating`` does nothing).
    """

    name = "quasi_dynamic"
    variable_dt = True

    def __init__(self, omega, dt=None, **_):
        super().__init__(omega)
        self.Y = np.zeros((self.nk, 0, 2))      # empty accumulators: frame shifts rotate nothing
        self._next_dt = None

    def begin_step(self, dt):
        pass

    def commit(self, vbar_k, dt):
        pass

    def prefill_translating(self, vhat_k, kabs, c, sigma=0.0, add=False):
        pass

    def shift(self, theta):
        pass

    def value(self) -> np.ndarray:
        return np.zeros(self.nk, dtype=complex)

    def state(self) -> dict:
        return {}

    def load_state(self, st: dict):
        pass

    @property
    def nbytes(self) -> int:
        return 0


#: Registry of history policies, selected by name in configs and tests.
HISTORY_POLICIES = {"full": FullHistory, "window": WindowHistory, "soe": SOEHistory,
                    "quasi_dynamic": QuasiDynamicHistory}


def make_history(name: str, omega, dt=None, **options) -> HistoryPolicy:
    """Build the history policy registered under ``name``."""
    try:
        cls = HISTORY_POLICIES[name]
    except KeyError:
        raise ValueError(f"history policy {name!r} unknown; choose one of {sorted(HISTORY_POLICIES)}")
    return cls(omega, dt, **options)


def wavenumbers(n: int, lam: float) -> np.ndarray:
    """|k| for the rfft modes of n points on a periodic domain of length λ, 1/m."""
    return 2.0 * math.pi / lam * np.arange(n // 2 + 1)


def elastic_functional(mu, kabs, delta_k, H_k):
    """f_k = −(μ|k|/2)(δ_k − H_k), Pa (times N in the unnormalised rfft convention)."""
    return -0.5 * mu * kabs * (delta_k - H_k)
