"""Seed the SBI time stepper with a steady pulse (docs/dynamic.md §3).

A steady pulse is a solution of the dynamic equations only if it has been travelling forever. This
module puts a steady pulse (any group that follows the HDF5 pulse schema of ``h5io``) on the uniform
periodic grid of the SBI stepper so that at t = 0 the discrete dynamic system is as close as possible
to the steady one:

* **fields**: ln v and ln φ interpolated (monotone cubic, PCHIP, on the solver's non-uniform grid),
  so v, φ > 0 and the leading edge is not smeared by overshoots;
* **history**: ``PredictorCorrector.set_translating_past(c_p)`` — the SOE accumulators hold the
  exact past of a profile that has translated at c_p forever;
* **slip**: the periodic travelling slip δ_k = iV_k/(kc_p), k ≠ 0, which differs from the slip of the
  isolated pulse by a uniform gradient only (no wrap dislocation; derivation in
  :func:`periodic_slip`);
* **loading**: τ_load = τ_d + η⟨V⟩, so that the uniform (k = 0) part of the stress is τ_d
  (the damping term −η⟨V − v_stick⟩ of the uniform mode is compensated; see :func:`uniform_load`),
  plus (default) the static far field τ_ff the period misses — the images removed, the cut tail
  added (:func:`far_field_stress`);
* **domain**: ``ahead`` pulse lengths ahead of the leading edge (plus the distance to travel) and
  ``behind`` pulse lengths of the healing tail; :func:`follow_pulse` keeps the pulse at a fixed
  place by shifting the periodic frame by whole cells and resetting the re-entering tail to rest,
  and moves τ_ff with the sub-cell front position.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from ..core import friction as fr
from ..steady.measures import pulse_length
from ..core.h5io import Pulse, read_pulse
from ..core.params import ParameterError, Parameters
from ..dynamics.sbi import elastic_functional
from ..dynamics.stepper import PredictorCorrector, RateStateInterface, TimeStepRule

#: The cheaper SOE node set of docs/dynamic.md §2 (36 nodes, kernel integral error ≤ 2e-5).
SOE_CHEAP = {"x_min": 1e-6, "x_max": 1e6, "h": 0.8}


#: Default SBI grid spacing of ``dynamic seed``/``verify`` in units of L0 = π μ D/(σ(f0 b − α)):
#: 2 mm for Table I (L0 = 0.88357 m), where it was chosen; scaling with L0 keeps it a fixed
#: fraction of the pulse's cohesive zone for other parameters (exact similarities).
DX_OVER_L0 = 2e-3 / 0.8835729338221293


def default_dx(params) -> float:
    """Default seeded grid spacing, m: :data:`DX_OVER_L0` · L0 (2 mm for Table I)."""
    return DX_OVER_L0 * params.L0


@dataclass(frozen=True)
class DomainSpec:
    """Periodic domain around a seeded pulse (lengths in units of the steady pulse length L).

    Attributes
    ----------
    dx : float
        Grid spacing Δx, m.
    ahead : float
        Distance from the leading edge (front half-maximum crossing) to the wrap, in L, kept free
        of the pulse's own tail during the run (the travel distance is added by ``travel``).
    behind : float
        Length of healing tail kept behind the front, in L (the pulse body itself is ≈ 1 L).
    travel : float
        Distance the pulse will travel, in L; added ahead when the frame does not follow the pulse.
    """

    dx: float = 1e-3
    ahead: float = 4.0
    behind: float = 4.0
    travel: float = 0.0

    def __post_init__(self):
        if not self.dx > 0 or not self.ahead > 0 or not self.behind > 1.0 or self.travel < 0:
            raise ParameterError("domain: need dx > 0 (m), ahead > 0, behind > 1 (pulse "
                                 "lengths) and travel >= 0")


@dataclass
class SeededPulse:
    """A stepper seeded with a steady pulse and what it was seeded from.

    Attributes
    ----------
    stepper : PredictorCorrector
    pulse : Pulse
        The steady pulse (infinite-line solution, non-uniform grid).
    params : Parameters
    xi_shift : float
        x = ξ + xi_shift maps the steady co-moving coordinate onto the periodic grid at t = 0, m.
    x_front0 : float
        Grid position of the front half-maximum crossing at t = 0, m.
    tau_steady : ndarray
        Steady stress τ(ξ) interpolated onto the grid (PCHIP of the file's τ), Pa.
    net_slip : float
        Δδ = ∫(V − v_stick) dx / c_p over the domain: the slip the pulse leaves behind, m.
    shift_cells : int
        Cells the frame has been shifted by (``follow_pulse``); x = x_grid + shift_cells·Δx.
    tau_ff : ndarray or None
        Far-field stress added to the loading at t = 0 (``far_field="steady"``), Pa.
    tau_load0 : float
        Uniform part of the loading, τ_d + η⟨V⟩_0, Pa.
    """

    stepper: PredictorCorrector
    pulse: Pulse
    params: Parameters
    xi_shift: float
    x_front0: float
    tau_steady: np.ndarray
    net_slip: float
    shift_cells: int = 0
    tau_ff: np.ndarray | None = None
    tau_load0: float = 0.0


def domain_size(L: float, spec: DomainSpec) -> tuple[int, float, float]:
    """Number of points N (even), period λ = NΔx and front position for a pulse of length L.

    Returns
    -------
    n : int
    length : float
        λ = N Δx ≥ (behind + ahead + travel)·L, m.
    x_front : float
        Grid position of the front crossing, behind·L from the left end, m.
    """
    want = (spec.behind + spec.ahead + spec.travel) * L
    n = int(math.ceil(want / spec.dx / 2.0)) * 2
    return n, n * spec.dx, spec.behind * L


def interpolate_log(xi_src, values, xi_new):
    """Monotone cubic interpolation of a positive field in log space: exp(PCHIP[ln u](ξ)).

    Parameters
    ----------
    xi_src : ndarray
        Ascending source abscissae (the steady solver's non-uniform grid), m.
    values : ndarray
        Positive samples u(ξ_src).
    xi_new : ndarray
        Target abscissae inside [ξ_src[0], ξ_src[-1]], m.

    Notes
    -----
    PCHIP preserves the monotonicity of ln u between nodes, so the interpolant introduces no new
    extrema: v stays between its neighbouring samples (no overshoot at the leading edge, where v
    rises by orders of magnitude within millimetres), and exp keeps it positive.
    """
    xi_new = np.asarray(xi_new, dtype=float)
    if xi_new.min() < xi_src[0] or xi_new.max() > xi_src[-1]:
        raise ParameterError(
            f"periodic domain [{xi_new.min():.4g}, {xi_new.max():.4g}] m exceeds the steady "
            f"solution's range [{xi_src[0]:.4g}, {xi_src[-1]:.4g}] m: reduce ahead/behind/travel")
    return np.exp(PchipInterpolator(xi_src, np.log(values))(xi_new))


def periodic_slip(V, dx, c):
    """Slip of a periodic slip-rate profile translating at c toward +x, without wrap dislocation.

    Parameters
    ----------
    V : ndarray
        Slip rate on the uniform periodic grid, m/s.
    dx : float
        Grid spacing, m.
    c : float
        Translation speed, m/s.

    Returns
    -------
    delta : ndarray
        δ(x) with zero mean, m (what ``set_translating_past`` builds: δ_k = iV_k/(kc), k ≠ 0).

    Notes
    -----
    For a profile translating at c, ∂δ/∂t = V and δ(x, t) = δ(x − ct), so −c ∂δ/∂x = V. The
    isolated pulse on the infinite line, resting at v_stick far ahead, has
    δ_∞(x) = (1/c)∫_x^∞ [V(z) − v_stick] dz (slip relative to creep): it rises from 0 ahead to
    the net slip Δδ = (1/c)∫[V − v_stick] dz behind. Put on a period λ this is a jump of Δδ at
    the wrap: a screw dislocation, whose stress μΔδ/(4πr) at distance r loads the pulse.
    The periodic solution of −c δ' = V − ⟨V⟩ (the k ≠ 0 modes of −cδ' = V) is

        δ(x) = δ_∞(x) + (Δδ/λ) x + const,   Δδ/λ = (⟨V⟩ − v_stick)/c,

    i.e. the isolated-pulse slip plus a **uniform slip gradient** that takes out the jump. A uniform
    gradient δ = s x has δ' = s constant, and the stress of a slip distribution depends on δ' only
    through the Hilbert transform, which annihilates constants (equivalently: s x is a rigid
    relative rotation-free shear of the two half-spaces, u_z = ±s x/2, with σ_yz = μ ∂u_z/∂y = 0).
    So the periodic slip carries exactly the stress of the isolated pulse's slip, up to the
    periodic images of the pulse. The missing ⟨V⟩ − v_stick is the k = 0 mode: uniform slip
    growth, which has no elastic stress (handled by the loading, see :func:`uniform_load`).
    """
    n = V.size
    Vk = np.fft.rfft(V)
    k = 2.0 * math.pi * np.arange(n // 2 + 1) / (n * dx)
    dk = np.zeros_like(Vk)
    dk[1:] = 1j * Vk[1:] / (k[1:] * c)
    return np.fft.irfft(dk, n)


def dislocated_slip(V, dx, c, v_stick):
    """Slip of the isolated pulse put on the period as is: a jump of Δδ left in at the wrap.

    δ_disl = δ_periodic + Δδ (1/2 − (j + 1/2)/N) at x_j = jΔx, Δδ = Σ(V − v_stick)Δx/c: by the
    derivation in :func:`periodic_slip` this is δ_∞ (up to a constant), which rises by Δδ from the
    front end (x → λ) to the tail end (x → 0); periodically that is a screw dislocation of Burgers
    vector Δδ at x_w = −Δx/2. For tests: its extra static stress,

        Δτ(x) = (μ/2π) PV∫ Δδ' (z)/(z − x) dz = −(μΔδ/2λ) cot(π(x − x_w)/λ),

    (periodic kernel; Δδ' = Δδ δ_D(x − x_w) − Δδ/λ, the uniform part giving none) loads the pulse.
    """
    n = V.size
    jump = float(np.sum(V - v_stick) * dx / c)
    saw = jump * (0.5 - (np.arange(n) + 0.5) / n)
    return periodic_slip(V, dx, c) + saw


def seed_pulse(pulse: Pulse, params: Parameters, spec: DomainSpec = DomainSpec(),
               rule: TimeStepRule | None = None, history_options=None, threads: int = 1,
               wrap_dislocation: bool = False, far_field: str = "steady",
               history_start: str = "steady", history: str = "soe") -> SeededPulse:
    """Put a steady pulse on the periodic SBI grid with its steady past (t = 0 of a verification).

    Parameters
    ----------
    pulse : Pulse
        Steady pulse (``h5io.read_pulse``): ξ ascending, travelling toward +ξ.
    params : Parameters
        The parameters the pulse was computed with.
    spec : DomainSpec
        Grid spacing and domain extents.
    rule : TimeStepRule, optional
        Default: adaptive steps, β_cfl = 0.5 (slow pulses need them).
    history_options : dict, optional
        SOE options (default :data:`SOE_CHEAP`).
    threads : int
    wrap_dislocation : bool
        For tests only: replace the periodic slip by the isolated pulse's slip, which jumps by the
        net slip Δδ at the wrap (:func:`dislocated_slip`).
    history : {"soe", "quasi_dynamic"}
        History policy of the stepper: the full kernel (SOE, seeded with the steady past) or, for
        the failure map only, the quasi-dynamic model (static stress + radiation damping,
        ``sbi.QuasiDynamicHistory``), in which the steady pulse of the full problem is not steady.
    history_start : {"steady", "rest"}
        ``"steady"``: the SOE history of a profile that translated at c_p forever. ``"rest"`` (for
        tests and the failure map only): the same periodic slip, but held static before t = 0
        (empty history), i.e. a history started at t = 0 — the slip rate is then resisted by the
        instantaneous elastic stiffness and a start-up transient is radiated.
    far_field : {"steady", "none"}
        ``"steady"``: add to the loading the static field τ_ff(x) = τ_steady(x) − τ_SBI(x, 0) that
        the periodic domain misses — the stress of the isolated pulse's slip rate outside the
        window minus that of the periodic images of the pulse — so that the t = 0 stress is the
        isolated pulse's. It is attached to the grid, so it must be used with
        :func:`follow_pulse` (the frame keeps the pulse at a fixed place). ``"none"``: the bare
        periodic problem (a train of pulses λ apart).

    Returns
    -------
    SeededPulse

    Notes
    -----
    Grid: x_j = jΔx, N = λ/Δx; the front half-maximum crossing ξ_R of ln(v/v*+1) is put at
    x = behind·L, so the domain keeps ξ ∈ [ξ_R − behind·L, ξ_R + (ahead + travel)·L].

    Fields: V = exp PCHIP[ln v], φ = exp PCHIP[ln φ] (:func:`interpolate_log`).

    Slip and history: :func:`start_stepper`. Loading: :func:`uniform_load`.

    Domain cost: the periodic stress differs from the isolated pulse's by the periodic images (cot
    kernel instead of 1/x) and the slip rate excess V − v_stick outside the window. The images
    dominate: (π/λ)cot(πy/λ) = 1/y − π²y/(3λ²) + O(y³/λ⁴), so a pulse with slip-rate integral
    ∫(V − v_stick) = c_pΔδ feels from its images the linear stress

        τ_img(x) ≈ +μF_III c_pΔδ (π²/3λ²)(x − x_c) = (π/6)√(1−β²) μΔδ (x − x_c)/λ²

    (x_c: centroid of V − v_stick), a gradient of 1.3e-3 τ_d per pulse length at 1.2 τ_min with
    λ = 8.6 L (measured 1.4e-3; it falls as 1/λ²). The slip rate cut off behind the window is a
    smaller effect (3e-5 τ_d at 4 L behind). ``far_field="steady"`` removes both
    (:func:`stress_mismatch` measures what is left).
    """
    check_seed_options(pulse, far_field, history, history_start)
    p = params
    L, _, xi_front = pulse_length(pulse.xi, pulse.v, p.v_star)
    n, lam, x_front = domain_size(L, spec)
    if rule is None:
        rule = TimeStepRule(kind="adaptive", beta_cfl=0.5)
    law = RateStateInterface(p, pulse.tau_d)
    st = PredictorCorrector(p, n, lam, law, rule=rule, history=history,
                            history_options=(dict(SOE_CHEAP if history_options is None
                                                  else history_options)
                                             if history == "soe" else {}), threads=threads)
    xi_shift = x_front - xi_front
    xi_grid = st.x - xi_shift
    V = interpolate_log(pulse.xi, pulse.v, xi_grid)
    phi = interpolate_log(pulse.xi, pulse.phi, xi_grid)
    tau_s = PchipInterpolator(pulse.xi, pulse.tau)(xi_grid)
    law.tau_load = uniform_load(pulse.tau_d, law.eta, V)
    tau_load0 = law.tau_load
    start_stepper(st, law, p, pulse, V, phi, history_start, wrap_dislocation)
    tau_ff = None
    if far_field == "steady":
        # τ_load(x) = τ_d + η⟨V⟩ + τ_ff(x): the isolated pulse's far field at t = 0
        tau_ff = far_field_stress(pulse, params, V, st.dx, xi_grid)
        law.tau_load = law.tau_load + tau_ff
        st.tau = st.tau + tau_ff
    net = float(np.sum(V - pulse.v_stick) * st.dx / pulse.c_p)
    return SeededPulse(stepper=st, pulse=pulse, params=p, xi_shift=xi_shift, x_front0=x_front,
                       tau_steady=tau_s, net_slip=net, tau_ff=tau_ff, tau_load0=tau_load0)


def check_seed_options(pulse: Pulse, far_field: str, history: str, history_start: str) -> None:
    """The options of :func:`seed_pulse`, checked before any grid is made (ParameterError naming
    the one that is invalid)."""
    if far_field not in ("steady", "none"):
        raise ParameterError(f"far_field={far_field!r} must be 'steady' or 'none'")
    if pulse.mode != "III":
        raise ParameterError(f"pulse mode {pulse.mode!r}: the SBI code is mode III only")
    if history not in ("soe", "quasi_dynamic"):
        raise ParameterError(f"history={history!r} must be 'soe' or 'quasi_dynamic'")
    if history_start not in ("steady", "rest"):
        raise ParameterError(f"history_start={history_start!r} must be 'steady' or 'rest'")


def uniform_load(tau_d: float, eta: float, V) -> float:
    """The seeded loading τ_load = τ_d + η⟨V⟩_0 (V: the seeded slip rate on the period).

    The SBI stress is τ = τ_load − ηV + f[δ, H] with f_0 = 0 (μ|k| = 0). For the
    translating profile the k ≠ 0 modes give exactly the steady operator,
    −ηV_k + f_k = −μF_III(β)·iπ sgn(k)V_k (docs/dynamic.md §1), while the uniform mode gives
    τ_load − η⟨V⟩. The isolated pulse has τ → τ_d with V → v_stick far ahead; on the period the
    uniform mode of V is ⟨V⟩ = v_stick + c_pΔδ/λ > v_stick, and radiation damping of that uniform
    excess would lower the stress everywhere by η c_pΔδ/λ (an artefact of the period, O(1/λ)).
    We therefore load with

        τ_load = τ_d + η⟨V⟩_0,

    which makes the uniform part of the stress τ_d, the value of the isolated pulse. Far ahead the
    seeded state is V = v_stick + O(1/ξ), φ = φ_ss(v_stick): σ f(v_stick, φ_ss) = τ_d, the rest state.
    (Loading with τ_d + η v_stick instead — the creep loading of ``RateStateInterface`` — would
    leave a uniform stress deficit η c_pΔδ/λ: 1.5 Pa, 4e-6 τ_d, at 1.2 τ_min, λ = 9 L.)
    """
    return tau_d + eta * float(V.mean())


def start_stepper(st, law, params: Parameters, pulse: Pulse, V, phi,
                  history_start: str = "steady", wrap_dislocation: bool = False) -> None:
    """The stepper's t = 0: state (V, φ), slip and history, and the stress under ``law``'s load.

    ``set_state(V, φ)`` then ``set_translating_past(c_p)``:
    δ_k = iV_k/(kc_p) (the periodic slip of :func:`periodic_slip`, no wrap dislocation) and the SOE
    accumulators at their steady values, so H_k(0) = ∫_0^∞ K(ω_k s)V_k(−s) ds.

    ``history_start="rest"``: the history emptied (slip static before t = 0);
    ``wrap_dislocation``: the isolated pulse's slip (:func:`dislocated_slip`) instead of the
    periodic one. Either recomputes the stress τ = τ_load − ηV + f[δ, H].
    """
    st.set_state(V, phi)
    st.set_translating_past(pulse.c_p)
    if history_start == "rest":
        st.history.Y[:] = 0.0                    # no past: slip static before t = 0
        f = st.fft.inverse(elastic_functional(params.mu, st.kabs, st.delta_k,
                                              st.history.value()))
        st.tau = law.tau_load - law.eta * st.V + f
    if wrap_dislocation:
        delta = dislocated_slip(V, st.dx, pulse.c_p, pulse.v_stick)
        st.delta = delta
        st.delta_k = st.fft.forward(delta).copy()
        H = st.history.value()
        f = st.fft.inverse(elastic_functional(params.mu, st.kabs, st.delta_k, H))
        st.tau = law.tau_load - law.eta * st.V + f


def far_field_stress(pulse: Pulse, params: Parameters, V, dx, xi_grid, pad: int = 64):
    """Stress of the isolated pulse that a periodic window misses: the images removed, the tail added.

    Parameters
    ----------
    pulse : Pulse
        The steady pulse (its grid extends far beyond the window).
    params : Parameters
    V : ndarray
        Seeded slip rate on the uniform periodic grid, m/s.
    dx : float
        Grid spacing, m.
    xi_grid : ndarray
        Steady coordinate ξ of the grid points, m.
    pad : int
        Zero padding factor of the line operator (its own images sit pad·λ away).

    Returns
    -------
    ndarray
        τ_ff(x), Pa.

    Notes
    -----
    With u = V − v_stick and the operator S[u] = −μF_III(β) PV∫ u(z)/(z − ξ) dz of the steady
    problem, the SBI stress of the seeded translating profile is τ_d + S_ring[u] (spectral, the
    multiplier −μF_III iπ sgn(k) on the period λ: the cot kernel, i.e. u plus all its images).
    The isolated pulse has τ_d + S_line[u_window] + S[u_outside]. Hence

        τ_ff = S_line[u] − S_ring[u] + S[u_outside],

    S_line by the same spectral multiplier on the samples zero-padded to pad·λ (images pad·λ
    away: their effect falls as 1/(pad λ)², 4096× smaller for pad = 64), S[u_outside] by the
    trapezoid rule on the steady grid outside the window (smooth inside it). Both operators act on
    the same samples, so τ_ff is smooth near the pulse: it carries no interpolation or
    leading-edge resolution error (which the t = 0 test therefore still sees).
    """
    n = V.size
    u = np.asarray(V, dtype=float) - pulse.v_stick
    mF = params.mu * float(params.F3(pulse.beta))

    def hilbert(vals, m):
        k = np.arange(m // 2 + 1)
        return np.fft.irfft(1j * math.pi * np.sign(k) * np.fft.rfft(vals, m), m)

    ring = hilbert(u, n)
    line = hilbert(u, pad * n)[:n]
    xi, us = pulse.xi, pulse.v - pulse.v_stick
    lo, hi = xi_grid[0] - 0.5 * dx, xi_grid[-1] + 0.5 * dx
    out = (xi < lo) | (xi > hi)
    w = np.zeros_like(xi)                      # trapezoid weights of the outside segments
    seg = np.diff(xi)
    both = out[:-1] & out[1:]
    w[:-1] += 0.5 * seg * both
    w[1:] += 0.5 * seg * both
    tail = np.zeros(n)
    idx = np.nonzero(w)[0]
    for c0 in range(0, n, 2048):
        xg = xi_grid[c0:c0 + 2048, None]
        tail[c0:c0 + 2048] = (w[idx] * us[idx] / (xi[idx][None, :] - xg)).sum(axis=1)
    return -mF * (line - ring + tail)


def seed_from_file(path: str, label: str | None = None, **kwargs) -> SeededPulse:
    """:func:`seed_pulse` for the pulse ``label`` of a steady family file (any schema-following file)."""
    pulse, params = read_pulse(path, label)
    return seed_pulse(pulse, params, **kwargs)


def stress_mismatch(seed: SeededPulse, window: tuple[float, float] = (-2.0, 1.0)) -> dict:
    """How far the t = 0 SBI stress is from the steady pulse's stress.

    Parameters
    ----------
    seed : SeededPulse
    window : (float, float)
        Region compared, in pulse lengths relative to the front crossing (default: the pulse
        body, its stress peak and the start of the tail).

    Returns
    -------
    dict
        ``stress``: max|τ_SBI − τ_steady|/τ_d over the window (τ_steady interpolated from the file);
        ``friction``: max|τ_SBI − σ f(V, φ)|/τ_d (the imbalance the first friction solve removes);
        ``stress_all``: the first over the whole domain.
    """
    st, pulse, p = seed.stepper, seed.pulse, seed.params
    rel = (st.x - seed.x_front0) / pulse.L
    inside = (rel >= window[0]) & (rel <= window[1])
    dtau = np.abs(st.tau - seed.tau_steady) / pulse.tau_d
    fric = np.abs(st.tau - p.sigma * fr.f(st.V, st.phi, *p.law_args)) / pulse.tau_d
    return {"stress": float(dtau[inside].max()), "friction": float(fric[inside].max()),
            "stress_all": float(dtau.max())}


def follow_pulse(seed: SeededPulse, x_front: float) -> int:
    """Shift the periodic frame by whole cells so that the front returns to ``seed.x_front0``.

    Parameters
    ----------
    seed : SeededPulse
    x_front : float
        Current front position on the grid, m.

    Returns
    -------
    int
        Cells shifted (0 when the front moved less than one cell).

    Notes
    -----
    A shift by m cells relabels the ring: a_j ← a_{j+m}, i.e. a_k ← a_k e^{2πikm/N} for every
    Fourier array (δ_k, V_k) and for the SOE accumulators, whose u and w parts (real and imaginary
    parts of V_k) mix by the rotation (Y⁽ᵘ⁾, Y⁽ʷ⁾) ← (cos θ Y⁽ᵘ⁾ − sin θ Y⁽ʷ⁾, sin θ Y⁽ᵘ⁾ + cos θ Y⁽ʷ⁾).
    This is exact (the ring is translation invariant); the far-field load (if any) is then placed
    at the sub-cell front position (:func:`_place_far_field`). The m cells that enter at the right end are
    the far end of the healing tail; they are reset to the rest state V = v_stick,
    φ = φ_ss(v_stick), so that the pulse keeps meeting rest material ahead. The reset is the only
    approximation: the tail material at behind·L has φ ≈ t_behind = behind·L/c_p (ageing) instead of
    φ_ss(v_stick), and V within O(1e-7) m/s of v_stick; its slip and history are kept.
    """
    st = seed.stepper
    m = int(math.floor((x_front - seed.x_front0) / st.dx))
    if m <= 0:
        _place_far_field(seed, x_front)
        return 0
    st.roll_frame(m, st.law.v_stick, st.law.phi_rest)   # SOE accumulators rotate too
    seed.shift_cells += m
    _place_far_field(seed, x_front - m * st.dx)
    return m


def _place_far_field(seed: SeededPulse, x_front: float) -> None:
    """Move the far-field load with the pulse: τ_load = τ_load0 + τ_ff(x − s), s = x_front − x_front0.

    s ∈ [0, Δx) after :func:`follow_pulse`; τ_ff(x − s) by linear interpolation between cells
    (τ_ff is smooth near the pulse: the error is O(Δx² τ_ff'') there). The pulse is very sensitive
    to the stress (docs/dynamic.md §3: a load misplaced by whole cells made v_max drift by 2e-2
    within 0.1 L at 1.2 τ_min), so the load follows the front continuously.
    """
    if seed.tau_ff is None:
        return
    st = seed.stepper
    a = min(max((x_front - seed.x_front0) / st.dx, 0.0), 1.0)
    st.place_load(seed.tau_load0, seed.tau_ff, a)


def write_seed(path: str, seed: SeededPulse, source: str = "", label: str = "") -> dict:
    """Write the seeded t = 0 state and its stress mismatch to HDF5 (atomically); returns the mismatch.

    Datasets (SI units as attributes): x, V, phi, delta, tau, tau_steady, tau_load (incl. the
    far field), tau_ff (if any). Root attributes: the mismatch of :func:`stress_mismatch`
    (``stress_mismatch``, ``friction_mismatch``, ``stress_mismatch_all``, in units of τ_d), the
    grid (n, dx, length), the pulse (tau_d_ratio, beta, c_p, L), x_front0, xi_shift, net_slip and
    the SOE history size, and ``steady_converged`` (False when the pulse was marked unconverged).
    """
    from ..core.h5io import atomic_update, coordinate, describe, stamp_format, write_parameters

    mis = stress_mismatch(seed)
    st, pulse = seed.stepper, seed.pulse

    def fill(h5):
        for key in list(h5.keys()):
            del h5[key]
        stamp_format(h5, "seed")
        write_parameters(h5, seed.params)
        load = np.broadcast_to(np.asarray(st.law.tau_load, dtype=float), st.V.shape)
        data = {"V": (st.V, "m/s", "slip rate"), "phi": (st.phi, "s", "state variable"),
                "delta": (st.delta, "m", "slip"), "tau": (st.tau, "Pa", "shear stress"),
                "tau_steady": (seed.tau_steady, "Pa", "steady pulse's shear stress"),
                "tau_load": (load, "Pa", "loading stress (with the far field)")}
        if seed.tau_ff is not None:
            data["tau_ff"] = (seed.tau_ff, "Pa", "far-field stress of the periodic images")
        x = coordinate(h5, "x", st.x, units="m", long_name="position on the SBI grid")
        for k, (v, unit, long) in data.items():
            describe(h5.create_dataset(k, data=v), unit, long, dims=(x,))
        a = h5.attrs
        a["stress_mismatch"] = mis["stress"]
        a["friction_mismatch"] = mis["friction"]
        a["stress_mismatch_all"] = mis["stress_all"]
        a["mismatch_units"] = "tau_d"
        a["n"], a["dx"], a["length"] = st.n, st.dx, st.length
        a["tau_d_ratio"], a["beta"], a["c_p"], a["L"] = (pulse.tau_d_ratio, pulse.beta,
                                                          pulse.c_p, pulse.L)
        a["x_front0"], a["xi_shift"], a["net_slip"] = seed.x_front0, seed.xi_shift, seed.net_slip
        a["history_bytes"] = st.history.nbytes
        a["steady_file"], a["label"] = source, label
        a["steady_converged"] = np.bool_(pulse.converged)   # False: seeded with --allow-unconverged

    atomic_update(path, fill, replace=True)
    return mis
