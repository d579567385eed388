"""Time stepping of the mode-III SBI interface: predictor–corrector, friction solve, state update.

A step from t_n to t_{n+1} = t_n + Δt (``PredictorCorrector._step_impl``; docs/dynamic.md §2):

    predict:  V̄ = V^n,  δ* = δ^n + Δt V̄,  φ* = S(φ^n, w(V^n), Δt)
              τ_el* = τ_load + f[δ*, V̄];  solve σ f(V*, φ*) + η V* = τ_el*
    correct:  V̄ = (V^n + V*)/2,  δ^{n+1} = δ^n + Δt V̄,  φ^{n+1} = S(φ^n, (w(V^n) + w(V*))/2, Δt)
              τ_el = τ_load + f[δ^{n+1}, V̄];  solve σ f(V^{n+1}, φ^{n+1}) + η V^{n+1} = τ_el
    commit:   history ← V̄

with η = μ/(2 c_s), S the exact state update at frozen healing rate (friction.state_step) and
f[δ, V̄]_k = −(μ|k|/2)(δ_k − H_k) the elastodynamic functional (sbi.py). Interface laws:
rate-and-state (the project's friction law), a prescribed rupture front with imposed stress drop
(Kostrov test) and prescribed kinematics (impose V(x, t), return τ).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from ..core import friction as fr
from .fft import RealFFT
from ..core.params import ParameterError, Parameters
from .sbi import HISTORY_POLICIES, elastic_functional, make_history, wavenumbers

#: Largest grid of the SBI: 2^22 points hold ≈ 5 GB in the SOE history alone (n/2 modes × 75
#: nodes × 2 complex accumulators); beyond it a run cannot fit a workstation's memory.
MAX_GRID_POINTS = 2 ** 22

# ----------------------------------------------------------------------------- friction solve


@numba.njit(cache=True)
def solve_point(tau_el, phi, v_guess, eta, sigma, f0, b, alpha, v_star, phi_star, D):
    """Root V ≥ 0 of F(V) = σ f(V, φ) + η V − τ_el by safeguarded Newton in x = ln V.

    Bracket: F(V_hi) ≥ 0 at V_hi = τ_el/η (σ f ≥ 0); F(V_lo) ≤ 0 at
    V_lo = τ_el/(σ A(φ)(f0 + α)/v* + η), because f ≤ A(φ)(f0 + α) V/v*. F is increasing in V.
    Newton steps leaving the bracket are replaced by bisection in ln V. Stops when |F| is at the
    rounding level of τ_el or after a Newton step |Δ ln V| < 1e-9 (the error is then O(Δ²)).
    Returns (V, iterations).
    """
    if not tau_el > 0.0:
        return 0.0, 0
    A = 1.0 + b * math.log1p(phi / phi_star)
    x_hi = math.log(tau_el / eta)
    x_lo = math.log(tau_el / (sigma * A * (f0 + alpha) / v_star + eta))
    if v_guess > 0.0:
        x = math.log(v_guess)
        if not (x_lo < x < x_hi):
            x = 0.5 * (x_lo + x_hi)
    else:
        x = 0.5 * (x_lo + x_hi)
    it = 0
    for it in range(1, 200):
        v = math.exp(x)
        F = sigma * fr.f(v, phi, f0, b, alpha, v_star, phi_star, D) + eta * v - tau_el
        if abs(F) <= 2.2e-16 * tau_el:
            return v, it                       # residual at the rounding level of τ_el
        if F > 0.0:
            x_hi = x
        else:
            x_lo = x
        dF = v * (sigma * fr.df_dv(v, phi, f0, b, alpha, v_star, phi_star, D) + eta)
        xn = x - F / dF
        # quadratic convergence: after a Newton step |dx| < 1e-9 the error is O(dx²) < 1e-17
        if abs(xn - x) < 1e-9:
            return math.exp(min(max(xn, x_lo), x_hi)), it
        if not (x_lo < xn < x_hi):
            xn = 0.5 * (x_lo + x_hi)         # safeguard: bisection in ln V
            if x_hi - x_lo < 1e-15 * max(1.0, abs(x)):
                return math.exp(xn), it
        x = xn
    return math.exp(x), it


@numba.njit(parallel=True, cache=True)
def solve_friction(tau_el, phi, v_guess, eta, sigma, f0, b, alpha, v_star, phi_star, D, v_out):
    """Solve σ f(V_i, φ_i) + η V_i = τ_el,i at every point; returns the largest iteration count."""
    its = np.empty(tau_el.size, dtype=np.int64)
    for i in numba.prange(tau_el.size):
        v, it = solve_point(tau_el[i], phi[i], v_guess[i], eta, sigma,
                             f0, b, alpha, v_star, phi_star, D)
        v_out[i] = v
        its[i] = it
    return its.max() if its.size else 0


# ----------------------------------------------------------------------------- interface laws


class RateStateInterface:
    """The project's rate-and-state law on the interface, loaded so that creep at v_stick has τ = τ_d.

    τ_load = τ_d + η v_stick: uniform creep (f ≡ 0 for uniform slip) is then an exact steady
    state of the discrete system.
    """

    has_state = True

    def __init__(self, params: Parameters, tau_d: float):
        params.check_tau_d(tau_d)
        self.params = params
        self.tau_d = float(tau_d)
        self.eta = params.mu / (2.0 * params.c_s)
        self.v_stick = params.v_stick(tau_d)
        self.phi_rest = params.phi_rest(tau_d)
        self.tau_load = self.tau_d + self.eta * self.v_stick

    def heal_rate(self, v):
        return fr.heal_rate(v, self.params.v_star, self.params.D)

    def solve(self, tau_el, phi, t, x, v_guess):
        """V from σ f(V, φ) + ηV = τ_el; τ = τ_el − ηV. Returns (V, τ, iterations)."""
        v = np.empty_like(tau_el)
        p = self.params
        it = solve_friction(tau_el, phi, v_guess, self.eta, p.sigma, *p.law_args, v)
        return v, tau_el - self.eta * v, it

    def stability_dt(self, v, phi, kmax):
        """Largest Δt for which the explicit elastic coupling stays stable (docs/dynamic.md §2):
        Δt ≤ 2 (σ ∂f/∂V + η)/k_s, k_s = μ k_max/2, the stiffest mode."""
        p = self.params
        stiff = p.sigma * fr.df_dv(v, phi, *p.law_args) + self.eta
        return float(2.0 * np.min(stiff) / (0.5 * p.mu * kmax))


class KostrovInterface:
    """Prescribed rupture front |x − x0| ≤ v_r t with imposed stress drop Δτ (Kostrov test).

    Inside the front τ = τ_load − Δτ, so V = (τ_el − τ_load + Δτ)/η; outside V = 0 and τ = τ_el.
    """

    has_state = False

    def __init__(self, params: Parameters, v_r: float, dtau: float, x0: float, tau_load: float = 0.0):
        self.params = params
        self.eta = params.mu / (2.0 * params.c_s)
        self.v_r, self.dtau, self.x0, self.tau_load = v_r, dtau, x0, tau_load

    def solve(self, tau_el, phi, t, x, v_guess):
        inside = np.abs(x - self.x0) <= self.v_r * t
        v = np.where(inside, (tau_el - self.tau_load + self.dtau) / self.eta, 0.0)
        return v, tau_el - self.eta * v, 0


class PrescribedInterface:
    """Prescribed kinematics: V(x, t) imposed by ``vfun(x, t)``; returns τ = τ_el − ηV."""

    has_state = False

    def __init__(self, params: Parameters, vfun, tau_load: float = 0.0):
        self.params = params
        self.eta = params.mu / (2.0 * params.c_s)
        self.vfun = vfun
        self.tau_load = tau_load

    def solve(self, tau_el, phi, t, x, v_guess):
        v = np.asarray(self.vfun(x, t), dtype=float)
        return v, tau_el - self.eta * v, 0


# ----------------------------------------------------------------------------- time-step rules


@dataclass(frozen=True)
class TimeStepRule:
    """How Δt is chosen (docs/dynamic.md §2).

    ``fixed``:     Δt = β_cfl Δx/c_s.
    ``adaptive``:  Δt* = min(Δt_max, ξ D/V_max, ξ_s Δt_stab, growth·Δt_prev), with Δt_stab the
                   explicit-elasticity stability bound of the interface law, rounded *down* to the
                   ladder Δt_cfl·ladder^j (j ≥ 0 integer), and never below Δt_cfl = β_cfl Δx/c_s,
                   the wave-resolving step. The ladder keeps the number of distinct Δt small,
                   so the history's per-Δt coefficients are reused (sbi.SOEHistory cache).
    """

    kind: str = "fixed"
    beta_cfl: float = 0.5
    xi: float = 0.1
    xi_stab: float = 0.5
    dt_max: float = math.inf
    growth: float = 1.2
    ladder: float = 2.0 ** 0.25

    def __post_init__(self):
        if self.kind not in ("fixed", "adaptive"):
            raise ParameterError(f"time.stepping={self.kind!r} must be 'fixed' or 'adaptive'")
        for name, lo, hi in (("beta_cfl", 0.0, 2.0), ("xi", 0.0, math.inf),
                             ("xi_stab", 0.0, math.inf), ("dt_max", 0.0, math.inf)):
            val = getattr(self, name)
            if not (lo < val <= hi):
                raise ParameterError(f"time.{name}={val!r} must be in ({lo}, {hi}]")
        if not self.growth > 1.0:
            raise ParameterError(f"time.growth={self.growth!r} must be > 1")
        if not self.ladder > 1.0:
            raise ParameterError(f"time.ladder={self.ladder!r} must be > 1")


# ----------------------------------------------------------------------------- steppers


class PredictorCorrector:
    """Second-order predictor–corrector SBI stepper (see module docstring).

    Parameters
    ----------
    params : Parameters
    n : int
        Number of grid points (even).
    length : float
        Periodic domain length λ, m.
    interface : RateStateInterface | KostrovInterface | PrescribedInterface
    rule : TimeStepRule
    history : str
        History policy name (sbi.HISTORY_POLICIES).
    history_options : dict
        Options of the policy (window periods/max_steps, SOE x_min/x_max/h).
    threads : int
        FFTW and numba threads.
    """

    name = "pc2"

    def __init__(self, params, n, length, interface, rule=TimeStepRule(), history="soe",
                 history_options=None, threads=1, planner="estimate"):
        if n < 4 or n % 2 or n > MAX_GRID_POINTS:
            raise ParameterError(f"grid.n={n!r} must be an even integer in [4, "
                                 f"{MAX_GRID_POINTS}]")
        if not length > 0:
            raise ParameterError(f"grid.length={length!r} must be > 0 (m)")
        self.params = params
        self.n = int(n)
        self.length = float(length)
        self.dx = self.length / self.n
        self.x = np.arange(self.n) * self.dx
        self.law = interface
        self.rule = rule
        self.eta = params.mu / (2.0 * params.c_s)
        self.kabs = wavenumbers(self.n, self.length)
        self.omega = self.kabs * params.c_s
        self.dt_cfl = rule.beta_cfl * self.dx / params.c_s
        self.threads = int(threads)
        numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
        self.fft = RealFFT(self.n, threads=self.threads, planner=planner)
        opts = dict(history_options or {})
        if history not in HISTORY_POLICIES:
            raise ParameterError(f"history.policy={history!r} unknown; choose one of "
                                 f"{sorted(HISTORY_POLICIES)}")
        if rule.kind == "adaptive" and not HISTORY_POLICIES[history].variable_dt:
            raise ParameterError(f"history.policy={history!r} needs time.stepping='fixed'; "
                                 "use 'soe' for adaptive steps")
        self.history_name = history
        self.history = make_history(history, self.omega,
                                    self.dt_cfl if rule.kind == "fixed" else None, **opts)
        # state
        self.t = 0.0
        self.nstep = 0
        self.dt_prev = self.dt_cfl
        self.delta = np.zeros(self.n)
        self.V = np.zeros(self.n)
        self.phi = np.zeros(self.n)
        self.tau = np.zeros(self.n)
        self.delta_k = np.zeros(self.n // 2 + 1, dtype=complex)
        self.V_k = np.zeros(self.n // 2 + 1, dtype=complex)
        self.iters = 0
        self.status = "initialised"
        self.message = ""

    # ------------------------------------------------------------------ initial conditions
    def set_state(self, V, phi=None, delta=None, tau=None):
        """Set V (m/s), φ (s), δ (m) at t = 0; τ defaults to τ_load − ηV + f[δ]."""
        self.V = np.array(np.broadcast_to(V, (self.n,)), dtype=float)
        self.phi = (np.zeros(self.n) if phi is None
                    else np.array(np.broadcast_to(phi, (self.n,)), dtype=float))
        self.delta = (np.zeros(self.n) if delta is None
                      else np.array(np.broadcast_to(delta, (self.n,)), dtype=float))
        self.delta_k = self.fft.forward(self.delta).copy()
        self.V_k = self.fft.forward(self.V).copy()
        if tau is None:
            f = self.fft.inverse(elastic_functional(self.params.mu, self.kabs, self.delta_k,
                                                    np.zeros_like(self.delta_k)))
            tau = self.law.tau_load - self.eta * self.V + f
        self.tau = np.array(tau, dtype=float)
        self.status = "ready"

    def set_creep(self):
        """Uniform creep at v_stick with φ = φ_ss(v_stick) and τ = τ_d (rate-and-state law)."""
        law = self.law
        self.set_state(np.full(self.n, law.v_stick), np.full(self.n, law.phi_rest))

    def set_gaussian(self, amplitude, width, position):
        """Creep plus a bump V = v_stick + A exp(−(x − x0)²/(2w²)) (periodic distance), with φ
        chosen so that friction balances the t = 0 stress τ = τ_d − η(V − v_stick) exactly:
        A(φ) = τ/(σ B(V)), φ = φ*(exp((A − 1)/b) − 1) where f = A(φ) B(V)."""
        p, law = self.params, self.law
        if not amplitude >= 0 or not width > 0:
            raise ParameterError("initial.amplitude must be >= 0 (m/s) and initial.width > 0 (m)")
        dxp = (self.x - position + 0.5 * self.length) % self.length - 0.5 * self.length
        V = law.v_stick + amplitude * np.exp(-0.5 * (dxp / width) ** 2)
        tau = law.tau_d - self.eta * (V - law.v_stick)
        B = fr.f(V, 0.0, *p.law_args)
        A = tau / (p.sigma * B)
        phi = p.phi_star * np.expm1((A - 1.0) / p.b)
        if not np.all(np.isfinite(phi)) or np.any(phi < 0) or np.any(tau <= 0):
            vmax = float(V.max())
            raise ParameterError(
                f"initial.amplitude={amplitude:g} m/s is too large: no state phi >= 0 balances "
                f"tau = tau_d - eta (V - v_stick) at V = {vmax:g} m/s; reduce the amplitude")
        self.set_state(V, phi, tau=tau)

    def set_translating_past(self, c):
        """Start as if the current V(x) had translated steadily at c (toward +x) since t = −∞:
        δ_k = iV_k/(kc) for k > 0 (the travelling slip; δ_0 kept) and the SOE history filled with
        the steady past (``SOEHistory.prefill_translating``), so τ starts at the steady-state
        stress and no start-up transient is radiated. Requires history policy 'soe'."""
        if self.history_name not in ("soe", "quasi_dynamic"):
            raise ParameterError("set_translating_past needs history.policy='soe' "
                                 "(or 'quasi_dynamic', which has no past)")
        if not c > 0:
            raise ParameterError(f"translation speed c={c!r} must be > 0 (m/s)")
        dk = np.zeros_like(self.V_k)
        dk[1:] = 1j * self.V_k[1:] / (self.kabs[1:] * c)
        dk[0] = self.delta_k[0]
        self.delta_k = dk
        self.delta = self.fft.inverse(dk).copy()
        self.history.prefill_translating(self.V_k, self.kabs, c)
        H = self.history.value()                 # H_k(0) = ∫_0^∞ K(ωs) V_k(−s) ds
        f = self.fft.inverse(elastic_functional(self.params.mu, self.kabs, self.delta_k, H))
        self.tau = self.law.tau_load - self.eta * self.V + f

    # ------------------------------------------------------------------ time step choice
    def next_dt(self) -> float:
        r = self.rule
        if r.kind == "fixed":
            return self.dt_cfl
        stab = (self.law.stability_dt(self.V, self.phi, self.kabs[-1])
                if isinstance(self.law, RateStateInterface) else None)
        return self._rule_dt(float(np.max(np.abs(self.V))), stab)

    def _rule_dt(self, vmax: float, stab: float | None) -> float:
        """The adaptive rule's Δt from max |V| and the stability bound (None: no bound)."""
        r = self.rule
        dt = min(r.dt_max, r.growth * self.dt_prev)
        if vmax > 0:
            dt = min(dt, r.xi * self.params.D / vmax)
        if stab is not None:
            dt = min(dt, r.xi_stab * stab)
        if dt <= self.dt_cfl:
            return self.dt_cfl
        j = math.floor(math.log(dt / self.dt_cfl) / math.log(r.ladder) + 1e-12)
        return self.dt_cfl * r.ladder ** j

    # ------------------------------------------------------------------ public step
    def step(self, dt: float | None = None) -> float:
        """Advance one step (Δt from the rule unless given); owns t, counters and status."""
        if dt is None:
            dt = self.next_dt()
        self._step_impl(dt)
        self.t += dt
        self.nstep += 1
        self.dt_prev = dt
        if not self._finite():
            self.status = "failed"
            self.message = f"non-finite V or tau at step {self.nstep}, t={self.t:.6g} s"
            raise FloatingPointError(self.message)
        self.status = "running"
        return dt

    def run(self, t_end=None, max_steps=None, callback=None):
        """Step until t ≥ t_end or max_steps steps (whichever first); callback(self) after each."""
        if t_end is None and max_steps is None:
            raise ValueError("run() needs t_end or max_steps")
        while True:
            if max_steps is not None and self.nstep >= max_steps:
                break
            if t_end is not None and self.t >= t_end * (1 - 1e-14):
                break
            self.step()
            if callback is not None:
                callback(self)
        self.status = "finished"
        return self

    def _finite(self) -> bool:
        """Whether V and τ are finite everywhere (checked after every step)."""
        return bool(np.all(np.isfinite(self.V)) and np.all(np.isfinite(self.tau)))

    def v_max(self) -> float:
        """Largest slip rate on the grid, m/s (a device stepper reduces it where the field is)."""
        return float(self.V.max())

    def slip_potency(self) -> float:
        """Σ δ Δx over the whole periodic ring, m²: the time integral of the potency rate Σ V Δx as
        the scheme advances it (δ += Δt V̄ each step). A frame roll permutes δ and keeps it, so
        this too does not see the frame (a device stepper sums it where the field is)."""
        return float(np.sum(self.delta)) * self.dx

    def peak_window(self, behind: int, ahead: int):
        """(x, V) on the cells from ``behind`` before to ``ahead`` after the largest V (clipped
        to the grid): what a front measurement needs, without the whole ring (views here)."""
        i = int(np.argmax(self.V))
        lo, hi = max(0, i - int(behind)), min(self.n, i + int(ahead) + 1)
        return self.x[lo:hi], self.V[lo:hi]

    def place_load(self, base: float, ff, a: float) -> None:
        """Loading τ_load = base + τ_ff shifted by a ∈ [0, 1] cells toward +x (linear
        interpolation between cells): the far field following the front (seeding.follow_pulse)."""
        self.law.tau_load = base + (1.0 - a) * ff + a * np.roll(ff, 1)

    def roll_frame(self, m: int, v_fill: float, phi_fill: float) -> None:
        """Relabel the periodic ring by m > 0 whole cells (a_j ← a_{j+m}) and put the m cells
        that enter at the right end at (v_fill, φ_fill), their slip and stress kept.

        Fourier arrays rotate by e^{2πikm/N} (δ_k exactly; V_k is the transform of the reset V),
        and so do the SOE accumulators (``SOEHistory.shift``). Used by ``seeding.follow_pulse``.
        """
        theta = 2.0 * math.pi * np.arange(self.n // 2 + 1) * m / self.n
        ph = np.exp(1j * theta)
        self.delta = np.roll(self.delta, -m)
        self.V = np.roll(self.V, -m)
        self.phi = np.roll(self.phi, -m)
        self.tau = np.roll(self.tau, -m)
        self.V[-m:] = v_fill
        self.phi[-m:] = phi_fill
        self.delta_k = self.delta_k * ph
        self.V_k = self.fft.forward(self.V).copy()
        self.history.shift(theta)

    # ------------------------------------------------------------------ physics
    def _functional(self, delta_k, vbar_k):
        """f = F⁻¹[−(μ|k|/2)(δ_k − H_k[V̄])], Pa."""
        H = self.history.current(vbar_k)
        return self.fft.inverse(elastic_functional(self.params.mu, self.kabs, delta_k, H)).copy()

    def _step_impl(self, dt):
        """One step t → t + Δt in four named stages (module docstring, docs/dynamic.md §2)."""
        t1 = self.t + dt
        self.history.begin_step(dt)                                  # sum the stored past once
        w_n, phi_star, f_star = self._predict(dt)
        v_star, _, it1 = self._solve_friction(f_star, phi_star, t1, self.V)
        vbar, vbar_k, delta_k, phi, f_new = self._correct(dt, w_n, v_star)
        v_new, tau_new, it2 = self._solve_friction(f_new, phi, t1, v_star)
        self._update_history(dt, vbar, vbar_k, delta_k, phi, v_new, tau_new)
        self.iters = max(it1, it2)

    def _predict(self, dt):
        """Predict: V̄ = V^n, δ* = δ^n + Δt V̄, φ* = S(φ^n, w(V^n), Δt), f* = f[δ*, V̄].

        Returns (w(V^n) or None, φ*, f*)."""
        vbar_k = self.V_k
        f_star = self._functional(self.delta_k + dt * vbar_k, vbar_k)
        if not self.law.has_state:
            return None, self.phi, f_star
        w_n = self.law.heal_rate(self.V)
        return w_n, fr.state_step(self.phi, w_n, dt), f_star

    def _solve_friction(self, f, phi, t1, v_guess):
        """Solve the interface law at each point: σ f(V, φ) + ηV = τ_load + f. Returns (V, τ, its)."""
        law = self.law
        return law.solve(law.tau_load + f, phi, t1, self.x, v_guess)

    def _correct(self, dt, w_n, v_star):
        """Correct: V̄ = (V^n + V*)/2, δ^{n+1} = δ^n + Δt V̄, φ^{n+1} = S(φ^n, (w(V^n) + w(V*))/2, Δt),
        f = f[δ^{n+1}, V̄]. Returns (V̄, V̄_k, δ^{n+1}_k, φ^{n+1}, f)."""
        vbar = 0.5 * (self.V + v_star)
        vbar_k = 0.5 * (self.V_k + self.fft.forward(v_star))
        delta_k = self.delta_k + dt * vbar_k
        if self.law.has_state:
            phi = fr.state_step(self.phi, 0.5 * (w_n + self.law.heal_rate(v_star)), dt)
        else:
            phi = self.phi
        return vbar, vbar_k, delta_k, phi, self._functional(delta_k, vbar_k)

    def _update_history(self, dt, vbar, vbar_k, delta_k, phi, v_new, tau_new):
        """Commit: the history stores the step average V̄; δ, φ, V, τ take their n+1 values."""
        self.history.commit(vbar_k, dt)
        self.delta = self.delta + dt * vbar
        self.delta_k = delta_k
        self.phi = phi
        self.V = v_new
        self.V_k = self.fft.forward(v_new).copy()
        self.tau = tau_new

    # ------------------------------------------------------------------ checkpoints
    def state(self) -> dict:
        """Everything needed to continue bit-exactly (arrays copied)."""
        st = {"t": np.float64(self.t), "nstep": np.int64(self.nstep),
              "dt_prev": np.float64(self.dt_prev), "delta": self.delta.copy(),
              "V": self.V.copy(), "phi": self.phi.copy(), "tau": self.tau.copy(),
              "delta_k": self.delta_k.copy(), "V_k": self.V_k.copy()}
        for key, val in self.history.state().items():
            st[f"history/{key}"] = val
        return st

    def load_state(self, st: dict):
        self.t = float(st["t"])
        self.nstep = int(st["nstep"])
        self.dt_prev = float(st["dt_prev"])
        for key in ("delta", "V", "phi", "tau", "delta_k", "V_k"):
            setattr(self, key, np.array(st[key]))
        self.history.load_state({k.split("/", 1)[1]: v for k, v in st.items()
                                 if k.startswith("history/")})
        self.status = "resumed"


#: Registry of steppers, selected by name.
STEPPERS = {"pc2": PredictorCorrector}


def make_stepper(name: str, *args, **kwargs):
    try:
        cls = STEPPERS[name]
    except KeyError:
        raise ParameterError(f"stepper={name!r} unknown; choose one of {sorted(STEPPERS)}")
    return cls(*args, **kwargs)
