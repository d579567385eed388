"""The SBI step on a GPU: the same predictor–corrector, friction solve and SOE history as
:class:`~slippulse.dynamics.stepper.PredictorCorrector`, with the fields kept in device memory.

A run is seeded on the host as always (``timedomain.seeding``, ``eigenmode``) and then handed over:
``DeviceStepper.from_host(stepper, "cupy")``. From then on each step runs on the GPU (CuPy: cuFFT
for the transforms, CUDA kernels for the friction solve and the two SOE sums, fused elementwise
kernels for the spectral right-hand sides and the state updates). Nothing else changes: the driver
still reads and writes the fields by name.

Host view of the fields
-----------------------
``delta, V, phi, tau, delta_k, V_k`` are properties. Reading one downloads it once per step and
returns a *read-only* copy (an in-place write would be lost, so it raises instead). Assigning one
(``st.V = ...``) makes the host array the current value until the next step or device query
(``v_max``, ``peak_window``, ``roll_frame``) uploads it; it stays writeable until then.
The loading ``law.tau_load`` is uploaded whenever it is a new object; ``place_load`` (the far
field following the front) computes it on the device. ``peak_window`` downloads only the cells
around the peak that the front measurement needs, and ``roll_frame`` shifts the ring on the device.
Per step the engine waits for the device once (max |V|, the step rule's stiffness bound,
finiteness and max V, fetched together). The SOE accumulators move to the device at the first
step and come back for ``state()`` and ``prefill_translating``.

Backends
--------
``"cupy"``: the GPU. ``"numpy"``: the same engine on the host with the host's own kernels (numba
friction solve and SOE sums, the stepper's FFT). It performs the very same floating-point
operations as ``PredictorCorrector``, so it reproduces a host run bit for bit; it exists to test
the engine's bookkeeping (field sync, frame shifts, Δt cache, loading upload) where there is no
GPU. The CUDA kernels are the line-by-line counterparts of ``stepper.solve_point``,
``friction.state_step`` and ``sbi.soe_past/soe_commit`` (compiled as C they give the numba
kernels' results bit for bit); ``tests/test_device.py`` compares a CuPy run with the host where
a GPU is present (docs/dynamic.md §5).

Scope: the rate-and-state interface with the SOE history (what the seeded runs use).
"""
from __future__ import annotations

import math

import numpy as np

from ..core import friction as fr
from ..core.params import ParameterError
from . import sbi
from .stepper import PredictorCorrector, RateStateInterface, solve_friction

#: The fields a stepper owns; on a DeviceStepper they live on the device.
FIELDS = ("delta", "V", "phi", "tau", "delta_k", "V_k")
BACKENDS = ("cupy", "numpy")


def cupy_unavailable() -> str | None:
    """Why the CuPy backend cannot run here (None when it can)."""
    try:
        import cupy
    except ImportError:
        return "CuPy is not installed"
    try:
        if cupy.cuda.runtime.getDeviceCount() < 1:
            return "no CUDA device"
    except Exception as exc:  # noqa: BLE001 - the driver's own error is the message
        return f"no usable CUDA device ({exc})"
    return None


# ----------------------------------------------------------------------------- backends


class _NumpyBackend:
    """The host's own kernels behind the backend interface (bit-identical to PredictorCorrector)."""

    name = "numpy"

    def __init__(self, fft, params):
        self.xp = np
        self._fft = fft
        self._p = params

    def asarray(self, a, dtype=None):
        return np.array(a, dtype=dtype, copy=True)

    def to_host(self, a):
        return np.array(a, copy=True)

    def rfft(self, u):
        return self._fft.forward(u).copy()

    def irfft(self, uk):
        return self._fft.inverse(uk).copy()

    def solve(self, tau_el, phi, v_guess, eta):
        p = self._p
        v = np.empty_like(tau_el)
        it = solve_friction(tau_el, phi, v_guess, eta, p.sigma, *p.law_args, v)
        return v, int(it)

    def state_step(self, phi, w, dt):
        return fr.state_step(phi, w, dt)

    def heal_rate(self, v):
        return fr.heal_rate(v, self._p.v_star, self._p.D)

    def stiffness_min(self, v, phi, eta):
        p = self._p
        return float(np.min(p.sigma * fr.df_dv(v, phi, *p.law_args) + eta))

    def abs_max(self, v):
        return float(np.max(np.abs(v)))

    def all_finite(self, *arrays):
        return all(bool(np.all(np.isfinite(a))) for a in arrays)

    def soe_past(self, E, Y, C, out):
        sbi.soe_past(E, Y, C, out)

    # the fused operations of a step, in the host stepper's order of operations
    def predict_rhs(self, coef, dk, Vk, past, w0, dt):
        return coef * ((dk + dt * Vk) - (past + w0 * Vk))

    def correct_rhs(self, coef, dk, Vk, Vsk, past, w0, dt):
        vbar_k = 0.5 * (Vk + Vsk)
        delta_k = dk + dt * vbar_k
        return vbar_k, delta_k, coef * (delta_k - (past + w0 * vbar_k))

    def predict_state(self, V, phi, dt):
        w_n = self.heal_rate(V)
        return w_n, fr.state_step(phi, w_n, dt)

    def correct_state(self, V, v_star, phi, w_n, dt):
        return 0.5 * (V + v_star), fr.state_step(phi, 0.5 * (w_n + self.heal_rate(v_star)), dt)

    def solve_stress(self, tl, f, phi, v_guess, eta):
        """V from σ f(V, φ) + ηV = τ_el = tl + f; returns (V, iterations, τ = τ_el − ηV)."""
        tau_el = tl + f
        v, it = self.solve(tau_el, phi, v_guess, eta)
        return v, it, tau_el - eta * v

    def advance(self, delta, vbar, dt):
        return delta + dt * vbar

    def stats(self, V, phi, tau, eta):
        """(max |V|, min(σ ∂f/∂V + η), all finite, max V): what the step rule and driver ask."""
        return (self.abs_max(V), self.stiffness_min(V, phi, eta), self.all_finite(V, tau),
                float(V.max()))

    def far_field(self, base, ff, a):
        return base + (1.0 - a) * ff + a * np.roll(ff, 1)

    def soe_commit(self, E, G, Y, V, C, past_next):
        sbi.soe_commit(E, G, Y, np.ascontiguousarray(V, dtype=complex), C, past_next)


_CUDA_LAW = r"""
__device__ double law_f(double v, double phi, double f0, double b, double alpha,
                        double vs, double ps) {
    double av = fabs(v);
    return (1.0 + b * log1p(phi / ps)) * (f0 * av / sqrt(v * v + vs * vs)
                                          + alpha * log1p(av / vs));
}
__device__ double law_dfdv(double v, double phi, double f0, double b, double alpha,
                           double vs, double ps) {
    double r2 = v * v + vs * vs;
    return (1.0 + b * log1p(phi / ps)) * (f0 * vs * vs / (r2 * sqrt(r2)) + alpha / (vs + fabs(v)));
}
"""

# stepper.solve_point, line by line (τ_el = tl + f; τ = τ_el − ηV is returned too)
_CUDA_SOLVE = r"""
double tau_el = tl + f;
if (!(tau_el > 0.0)) { v = 0.0; it = 0; }
else {
    double A = 1.0 + b * log1p(phi / ps);
    double x_hi = log(tau_el / eta);
    double x_lo = log(tau_el / (sigma * A * (f0 + alpha) / vs + eta));
    double x;
    if (v_guess > 0.0) {
        x = log(v_guess);
        if (!(x_lo < x && x < x_hi)) x = 0.5 * (x_lo + x_hi);
    } else {
        x = 0.5 * (x_lo + x_hi);
    }
    int k;
    int done = 0;
    double res = 0.0;
    for (k = 1; k < 200; k++) {
        double vv = exp(x);
        double F = sigma * law_f(vv, phi, f0, b, alpha, vs, ps) + eta * vv - tau_el;
        if (fabs(F) <= 2.2e-16 * tau_el) { res = vv; done = 1; break; }
        if (F > 0.0) x_hi = x; else x_lo = x;
        double dF = vv * (sigma * law_dfdv(vv, phi, f0, b, alpha, vs, ps) + eta);
        double xn = x - F / dF;
        if (fabs(xn - x) < 1e-9) { res = exp(fmin(fmax(xn, x_lo), x_hi)); done = 1; break; }
        if (!(x_lo < xn && xn < x_hi)) {
            xn = 0.5 * (x_lo + x_hi);
            if (x_hi - x_lo < 1e-15 * fmax(1.0, fabs(x))) { res = exp(xn); done = 1; break; }
        }
        x = xn;
    }
    if (!done) { res = exp(x); k = 199; }
    v = res;
    it = k;
}
tau = tau_el - eta * v;
"""

# friction.state_step
_CUDA_STATE = r"""
__device__ double state_step(double phi, double w, double dt) {
    double x = w * dt;
    if (x < 1e-300) return phi + dt;
    double pss = 1.0 / w;
    double d = phi - pss;
    if (fabs(d) <= pss) return pss + d * exp(-x);
    return phi * exp(-x) - dt * expm1(-x) / x;
}
"""

# sbi.soe_past and sbi.soe_commit on the host layout Y[k, j, c] (complex, c = u, w)
_CUDA_SOE = r"""
extern "C" __global__ void soe_past(const double* E, const double* Y, const double* C,
                                    double* out, long long nk, long long p) {
    long long k = (long long)blockDim.x * blockIdx.x + threadIdx.x;
    if (k >= nk) return;
    double s1 = 0.0, s2 = 0.0;
    for (long long j = 0; j < p; j++) {
        long long ij = k * p + j;
        double er = E[2 * ij], ei = E[2 * ij + 1];
        double cr = C[2 * j], ci = C[2 * j + 1];
        double cer = cr * er - ci * ei, cei = cr * ei + ci * er;
        const double* y = Y + 4 * ij;
        s1 += cer * y[0] - cei * y[1];
        s2 += cer * y[2] - cei * y[3];
    }
    out[2 * k] = s1;
    out[2 * k + 1] = s2;
}

extern "C" __global__ void soe_commit(const double* E, const double* G, double* Y,
                                      const double* V, const double* C, double* past_next,
                                      long long nk, long long p) {
    long long k = (long long)blockDim.x * blockIdx.x + threadIdx.x;
    if (k >= nk) return;
    double u = V[2 * k], w = V[2 * k + 1];
    double s1 = 0.0, s2 = 0.0;
    for (long long j = 0; j < p; j++) {
        long long ij = k * p + j;
        double er = E[2 * ij], ei = E[2 * ij + 1];
        double gr = G[2 * ij], gi = G[2 * ij + 1];
        double* y = Y + 4 * ij;
        double a_r = er * y[0] - ei * y[1] + gr * u;
        double a_i = er * y[1] + ei * y[0] + gi * u;
        double b_r = er * y[2] - ei * y[3] + gr * w;
        double b_i = er * y[3] + ei * y[2] + gi * w;
        y[0] = a_r; y[1] = a_i; y[2] = b_r; y[3] = b_i;
        double cr = C[2 * j], ci = C[2 * j + 1];
        double cer = cr * er - ci * ei, cei = cr * ei + ci * er;
        s1 += cer * a_r - cei * a_i;
        s2 += cer * b_r - cei * b_i;
    }
    past_next[2 * k] = s1;
    past_next[2 * k + 1] = s2;
}
"""


class _CupyBackend:
    """CuPy arrays, cuFFT, and the CUDA kernels above."""

    name = "cupy"
    _BLOCK = 256

    def __init__(self, n, params):
        why = cupy_unavailable()
        if why:
            raise ParameterError(f"device='cupy' cannot run here: {why}")
        import cupy as cp
        self.xp = cp
        self.n = int(n)
        self._p = params
        law = _CUDA_LAW + _CUDA_STATE
        self._solve = cp.ElementwiseKernel(
            "float64 tl, float64 f, float64 phi, float64 v_guess, float64 eta, float64 sigma, "
            "float64 f0, float64 b, float64 alpha, float64 vs, float64 ps",
            "float64 v, int32 it, float64 tau", _CUDA_SOLVE, "slippulse_solve", preamble=law)
        self._stiff = cp.ElementwiseKernel(
            "float64 v, float64 phi, float64 sigma, float64 f0, float64 b, float64 alpha, "
            "float64 vs, float64 ps, float64 eta", "float64 s",
            "s = sigma * law_dfdv(v, phi, f0, b, alpha, vs, ps) + eta", "slippulse_stiff",
            preamble=law)
        self._pred_rhs = cp.ElementwiseKernel(
            "float64 coef, complex128 dk, complex128 Vk, complex128 past, float64 w0, float64 dt",
            "complex128 out", "out = coef * ((dk + dt * Vk) - (past + w0 * Vk))",
            "slippulse_pred_rhs")
        self._corr_rhs = cp.ElementwiseKernel(
            "float64 coef, complex128 dk, complex128 Vk, complex128 Vsk, complex128 past, "
            "float64 w0, float64 dt", "complex128 vbar_k, complex128 delta_k, complex128 out",
            "vbar_k = 0.5 * (Vk + Vsk); delta_k = dk + dt * vbar_k; "
            "out = coef * (delta_k - (past + w0 * vbar_k))", "slippulse_corr_rhs")
        self._pred_state = cp.ElementwiseKernel(
            "float64 V, float64 phi, float64 vs, float64 D, float64 dt",
            "float64 w_n, float64 phi_star",
            "w_n = sqrt(V * V + vs * vs) / D; phi_star = state_step(phi, w_n, dt)",
            "slippulse_pred_state", preamble=law)
        self._corr_state = cp.ElementwiseKernel(
            "float64 V, float64 vst, float64 phi, float64 w_n, float64 vs, float64 D, float64 dt",
            "float64 vbar, float64 phi_new",
            "vbar = 0.5 * (V + vst); "
            "phi_new = state_step(phi, 0.5 * (w_n + sqrt(vst * vst + vs * vs) / D), dt)",
            "slippulse_corr_state", preamble=law)
        self._advance = cp.ElementwiseKernel(
            "float64 delta, float64 vbar, float64 dt", "float64 out", "out = delta + dt * vbar",
            "slippulse_advance")
        mod = cp.RawModule(code=_CUDA_SOE)
        self._past = mod.get_function("soe_past")
        self._commit = mod.get_function("soe_commit")

    def asarray(self, a, dtype=None):
        return self.xp.array(a, dtype=dtype, copy=True)

    def to_host(self, a):
        return self.xp.asnumpy(a)

    def rfft(self, u):
        return self.xp.fft.rfft(u)

    def irfft(self, uk):
        return self.xp.fft.irfft(uk, n=self.n)

    def solve_stress(self, tl, f, phi, v_guess, eta):
        p = self._p
        f0, b, alpha, vs, ps, _ = p.law_args
        v, it, tau = self._solve(tl, f, phi, v_guess, eta, p.sigma, f0, b, alpha, vs, ps)
        return v, it.max(), tau             # a device scalar: no wait for the GPU here

    def predict_rhs(self, coef, dk, Vk, past, w0, dt):
        return self._pred_rhs(coef, dk, Vk, past, w0, float(dt))

    def correct_rhs(self, coef, dk, Vk, Vsk, past, w0, dt):
        return self._corr_rhs(coef, dk, Vk, Vsk, past, w0, float(dt))

    def predict_state(self, V, phi, dt):
        return self._pred_state(V, phi, self._p.v_star, self._p.D, float(dt))

    def correct_state(self, V, v_star, phi, w_n, dt):
        return self._corr_state(V, v_star, phi, w_n, self._p.v_star, self._p.D, float(dt))

    def advance(self, delta, vbar, dt):
        return self._advance(delta, vbar, float(dt))

    def stats(self, V, phi, tau, eta):
        """The same four numbers as the numpy backend, in one transfer."""
        xp, p = self.xp, self._p
        f0, b, alpha, vs, ps, _ = p.law_args
        stiff = self._stiff(V, phi, p.sigma, f0, b, alpha, vs, ps, eta)
        # V ≥ 0 (the solve returns 0 or e^x), so max V = max |V|; a NaN or inf in V shows in its
        # max, one in τ in its sum (|τ| ≲ 1e8 Pa: the sum of finite values cannot overflow)
        vals = xp.stack([V.max(), stiff.min(), tau.sum()]).get()
        vmax = float(vals[0])
        return vmax, float(vals[1]), math.isfinite(vmax) and math.isfinite(vals[2]), vmax

    def far_field(self, base, ff, a):
        return base + (1.0 - a) * ff + a * self.xp.roll(ff, 1)

    def soe_past(self, E, Y, C, out):
        nk, p = E.shape
        grid = ((nk + self._BLOCK - 1) // self._BLOCK,)
        self._past(grid, (self._BLOCK,), (E, Y, C, out, np.int64(nk), np.int64(p)))

    def soe_commit(self, E, G, Y, V, C, past_next):
        nk, p = E.shape
        grid = ((nk + self._BLOCK - 1) // self._BLOCK,)
        self._commit(grid, (self._BLOCK,), (E, G, Y, self.xp.ascontiguousarray(V), C, past_next,
                                            np.int64(nk), np.int64(p)))


def make_backend(name, fft, params):
    if name == "numpy":
        return _NumpyBackend(fft, params)
    if name == "cupy":
        return _CupyBackend(fft.n, params)
    raise ParameterError(f"device={name!r} unknown; choose one of {list(BACKENDS)}")


# ----------------------------------------------------------------------------- SOE history


class DeviceSOEHistory:
    """``sbi.SOEHistory`` with its accumulators on the device during stepping.

    Wraps the host history the run was seeded with: ``prefill_translating`` and ``load_state``
    act on the host object (the accumulators come back first if they are on the device);
    ``begin_step``/``current``/``commit``/``shift`` act on the device (they go there first).
    The per-Δt coefficients (E, G, w0) are computed by the host object, as on the host, and kept
    on the device for the last ``cache_size`` distinct Δt.
    """

    name = "soe"
    variable_dt = True

    def __init__(self, host: sbi.SOEHistory, backend):
        if not isinstance(host, sbi.SOEHistory):
            raise ParameterError(f"a device run needs the 'soe' history, not {host.name!r}")
        self.host = host
        self.be = backend
        xp = backend.xp
        self.omega, self.nk, self.p = host.omega, host.nk, host.p
        self.Z, self.C = host.Z, host.C
        self._C = backend.asarray(host.C)
        self.Y = None
        self.on_device = False
        self._cache = {}
        self.cache_size = host.cache_size
        self._past = xp.zeros(self.nk, dtype=complex)
        self._past_next = xp.zeros(self.nk, dtype=complex)
        self._E = self._G = self._w0 = None
        self._dt = None
        self._next_dt = None

    @property
    def count(self) -> int:
        return self.host.count

    def _to_device(self):
        if not self.on_device:
            self.Y = self.be.asarray(self.host.Y)
            self.on_device = True
            self._next_dt = None

    def _to_host(self):
        if self.on_device:
            self.host.Y[...] = self.be.to_host(self.Y)
            self.Y = None
            self.on_device = False
            self._next_dt = None

    def _set_dt(self, dt):
        if self._dt == dt:
            return
        self._dt = dt
        self._E, self._G, self._w0 = sbi.lru_lookup(self._cache, dt, self.cache_size,
                                                    lambda: self._upload_factors(dt))

    def _upload_factors(self, dt):
        """The host history's (E, G, w0) of Δt = dt, on the device."""
        E, G, w0 = self.host.factors_at(dt)
        return self.be.asarray(E), self.be.asarray(G), self.be.asarray(w0)

    def begin_step(self, dt):
        dt = float(dt)
        self._to_device()
        if self._next_dt == dt:
            self._past[...] = self._past_next
        else:
            self._set_dt(dt)
            self.be.soe_past(self._E, self.Y, self._C, self._past)

    def current(self, vbar_k):
        return self._past + self._w0 * vbar_k

    def past_and_weight(self):
        """The summed past and the current interval's weight: H = past + w0 V̄ (``current``)."""
        return self._past, self._w0

    def commit(self, vbar_k, dt):
        self._set_dt(float(dt))
        self.be.soe_commit(self._E, self._G, self.Y, vbar_k, self._C, self._past_next)
        self._next_dt = float(dt)
        self.host.count += 1

    def prefill_translating(self, *args, **kwargs):
        self._to_host()
        self.host.prefill_translating(*args, **kwargs)

    def shift(self, theta) -> None:
        """``SOEHistory.shift`` where the accumulators are (the same operations)."""
        if not self.on_device:
            self.host.shift(theta)
            return
        xp = self.xp
        th = theta if isinstance(theta, xp.ndarray) else self.be.asarray(np.asarray(theta, float))
        sbi.rotate_accumulators(self.Y, xp.cos(th), xp.sin(th))
        self._next_dt = None

    @property
    def xp(self):
        return self.be.xp

    def value(self) -> np.ndarray:
        if not self.on_device:
            return self.host.value()
        xp = self.xp
        aY = xp.einsum("j,kjc->kc", self._C, self.Y)
        return self.be.to_host(aY[:, 0].real + 1j * aY[:, 1].real)

    def state(self) -> dict:
        Y = self.be.to_host(self.Y) if self.on_device else self.host.Y.copy()
        return {"Y": Y, "count": np.int64(self.count)}

    def load_state(self, st: dict):
        self.Y = None
        self.on_device = False
        self.host.load_state(st)
        self._dt = None
        self._next_dt = None

    @property
    def nbytes(self) -> int:
        return self.host.nbytes


# ----------------------------------------------------------------------------- the stepper


def _field(name):
    def get(self):
        h = self._host.get(name)
        if h is not None:
            return h
        ro = self._ro.get(name)
        if ro is None:
            ro = self.be.to_host(self._dev[name])
            ro.flags.writeable = False
            self._ro[name] = ro
        return ro

    def put(self, value):
        self._host[name] = np.asarray(value)
        self._ro.pop(name, None)
        self._st = None

    return property(get, put, doc=f"{name} (host view; see the module notes)")


class _OnDevice:
    """A loading array that lives on the device (``law.tau_load`` after ``place_load``):
    np.asarray(...) downloads it."""

    def __init__(self, backend, a):
        self._be, self.a = backend, a

    def __array__(self, dtype=None, copy=None):
        out = self._be.to_host(self.a)
        return out if dtype is None else out.astype(dtype)


class DeviceStepper(PredictorCorrector):
    """``PredictorCorrector`` whose fields and SOE history live on a device (module notes).

    Make one from a seeded host stepper with :meth:`from_host`; step it like the host one.
    Per step it waits for the device once (:meth:`_stats`: max |V|, the stiffness bound of the
    step rule, finiteness and max V, fetched together).
    """

    name = "pc2_device"

    delta = _field("delta")
    V = _field("V")
    phi = _field("phi")
    tau = _field("tau")
    delta_k = _field("delta_k")
    V_k = _field("V_k")

    @classmethod
    def from_host(cls, host: PredictorCorrector, backend: str = "cupy") -> "DeviceStepper":
        """Take over a seeded host stepper (its fields, history, law, rule, clock and counters)."""
        if not isinstance(host.law, RateStateInterface):
            raise ParameterError("a device run needs the rate-and-state interface")
        if host.history_name != "soe":
            raise ParameterError(f"a device run needs history 'soe', not {host.history_name!r}")
        obj = cls.__new__(cls)
        d = dict(host.__dict__)
        obj.__dict__.update({"_host": {}, "_ro": {}, "_dev": {}})
        for key in FIELDS:
            obj._host[key] = d.pop(key)
        d.pop("iters", None)
        obj.__dict__.update(d)
        obj.be = make_backend(backend, host.fft, host.params)
        obj.history = DeviceSOEHistory(host.history, obj.be)
        obj._coef = obj.be.asarray(-0.5 * host.params.mu * host.kabs)
        obj._tl_src = obj._tl_dev = None
        obj._ff_src = obj._ff_dev = None
        obj._st = None
        obj._its = None
        return obj

    @property
    def backend(self) -> str:
        return self.be.name

    @property
    def iters(self) -> int:
        """Largest friction-solve iteration count of the last step."""
        its = self.__dict__.get("_its")
        return 0 if its is None else max(int(i) for i in its)

    # ------------------------------------------------------------------ host/device sync
    def _push(self):
        """Upload the fields assigned on the host since the last step."""
        if self._host:
            for key, arr in self._host.items():
                self._dev[key] = self.be.asarray(arr, dtype=complex if key.endswith("_k")
                                                 else float)
            self._host.clear()
            self._st = None
        self._ro.clear()

    def _tau_load(self):
        tl = self.law.tau_load
        if tl is not self._tl_src:
            self._tl_dev = float(tl) if np.ndim(tl) == 0 else self.be.asarray(tl, dtype=float)
            self._tl_src = tl
        return self._tl_dev

    def _stats(self):
        if self._st is None:
            self._push()
            d = self._dev
            self._st = self.be.stats(d["V"], d["phi"], d["tau"], self.law.eta)
        return self._st

    # ------------------------------------------------------------------ the driver's queries
    def v_max(self) -> float:
        return self._stats()[3]

    def slip_potency(self) -> float:
        """``PredictorCorrector.slip_potency``, summed on the device (one scalar back)."""
        self._push()
        return float(self.be.xp.sum(self._dev["delta"])) * self.dx

    def peak_window(self, behind: int, ahead: int):
        """``PredictorCorrector.peak_window``, downloading only the window."""
        self._push()
        V = self._dev["V"]
        i = int(self.be.xp.argmax(V))
        lo, hi = max(0, i - int(behind)), min(self.n, i + int(ahead) + 1)
        return self.x[lo:hi], self.be.to_host(V[lo:hi])

    def place_load(self, base: float, ff, a: float) -> None:
        """``PredictorCorrector.place_load`` on the device (τ_ff uploaded once)."""
        if ff is not self._ff_src:
            self._ff_dev = self.be.asarray(ff, dtype=float)
            self._ff_src = ff
        tl = self.be.far_field(base, self._ff_dev, a)
        self._tl_dev = tl
        self.law.tau_load = self._tl_src = _OnDevice(self.be, tl) if self.be.name != "numpy" else tl

    # ------------------------------------------------------------------ stepping
    def next_dt(self) -> float:
        if self.rule.kind == "fixed":
            return self.dt_cfl
        vmax, stiff, _, _ = self._stats()
        return self._rule_dt(vmax, float(2.0 * stiff / (0.5 * self.params.mu * self.kabs[-1])))

    def _finite(self) -> bool:
        return self._stats()[2]

    def _step_impl(self, dt):
        """``PredictorCorrector._step_impl`` on the device, the same operations in the same order
        (fused into a few kernels on the GPU)."""
        self._push()
        be, d, hist, eta = self.be, self._dev, self.history, self.law.eta
        tl = self._tau_load()
        hist.begin_step(dt)
        V, Vk, phi, dk = d["V"], d["V_k"], d["phi"], d["delta_k"]
        past, w0 = hist.past_and_weight()
        # predict
        f_star = be.irfft(be.predict_rhs(self._coef, dk, Vk, past, w0, dt))
        w_n, phi_star = be.predict_state(V, phi, dt)
        v_star, it1, _ = be.solve_stress(tl, f_star, phi_star, V, eta)
        # correct
        vbar_k, delta_k, rhs = be.correct_rhs(self._coef, dk, Vk, be.rfft(v_star), past, w0, dt)
        vbar, phi_new = be.correct_state(V, v_star, phi, w_n, dt)
        v_new, it2, tau_new = be.solve_stress(tl, be.irfft(rhs), phi_new, v_star, eta)
        # commit
        hist.commit(vbar_k, dt)
        d["delta"] = be.advance(d["delta"], vbar, dt)
        d["delta_k"] = delta_k
        d["phi"] = phi_new
        d["V"] = v_new
        d["V_k"] = be.rfft(v_new)
        d["tau"] = tau_new
        self._ro.clear()
        self._st = None
        self._its = (it1, it2)

    def roll_frame(self, m: int, v_fill: float, phi_fill: float) -> None:
        """``PredictorCorrector.roll_frame`` on the device."""
        self._push()
        be, d, xp = self.be, self._dev, self.be.xp
        if be.name == "numpy":
            theta = 2.0 * math.pi * np.arange(self.n // 2 + 1) * m / self.n
            ph = np.exp(1j * theta)
        else:
            theta = 2.0 * math.pi * xp.arange(self.n // 2 + 1, dtype=xp.float64) * m / self.n
            ph = xp.exp(1j * theta)
        for key in ("delta", "V", "phi", "tau"):
            d[key] = xp.roll(d[key], -m)
        d["V"][-m:] = v_fill
        d["phi"][-m:] = phi_fill
        d["delta_k"] = d["delta_k"] * ph
        d["V_k"] = be.rfft(d["V"])
        self.history.shift(theta)
        self._ro.clear()
        self._st = None

    def load_state(self, st: dict):
        super().load_state(st)
        self._dev.clear()
        self._st = None
