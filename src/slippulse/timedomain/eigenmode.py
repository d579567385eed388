"""The unstable eigenmode of a steady pulse in time: source of growth rates, SBI seed, front frame.

The linear stability spectrum (:mod:`slippulse.spectrum.pulse`, docs/spectrum.md) gives, per
pulse, the leading eigenvalue σ and its mode (δ₁, V₁, φ₁) on the pulse's own grid, normalised so
that the perturbation of y = ln(v/v* + 1), y₁ = V₁/(v₀ + v*), has modulus 1 and phase 0 at its
largest modulus. This module

* reads that mode from the pulse's file (``/pulses/<label>/spectrum``, written by
  ``slippulse steady stability``) or computes it on the fly (:func:`leading_mode`), and refuses a
  mode that belongs to another pulse (:func:`check_same_pulse`);
* seeds the SBI with the steady pulse plus ε × mode, with the past of an eternal translation that
  also grew as e^{σt} (:func:`perturb_along_mode`; derivation in docs/stability.md §2);
* expresses the mode as the SBI measures it, at fixed distance from the front, with its first-order
  change of the front speed and of the pulse length (:func:`front_response`);
* compares it with the family tangent d(y, ln φ)/dτ_d in the same front frame
  (:func:`family_tangent`, :func:`mode_overlap`, :func:`family_overlaps`; docs/stability.md §4).

Import direction: core, steady, dynamics → stability (this module uses ``spectrum`` and
``seeding``; ``verify`` and ``perturbation`` use it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline, PchipInterpolator

from ..core.h5io import state_order_of
from ..core.params import ParameterError
from ..steady.measures import pulse_length

#: Largest |ε| accepted for a mode-seeded run: ε is the largest change of y = ln(v/v*+1)
#: (≈ the relative change of the peak slip rate). The ±ε growth fit (perturbation.pair_growth)
#: counts the response as linear while |v_max/v_max⁰ − 1| ≤ 0.03; a seed of |ε| ≤ 0.01 leaves
#: ≥ ln 3 ≈ 1.1 e-folds of linear growth, and the antisymmetric response of a pair carries the
#: cubic error O(ε²) ≤ 1e-4 relative (docs/stability.md §2).
EPS_MAX = 1e-2
#: |Im σ| / Re σ above which the leading eigenvalue counts as complex (not seedable: the seed
#: would need the conjugate pair).
REAL_TOL = 1e-6
#: Window of the front-frame comparisons, in pulse lengths L relative to the front crossing
#: (the SBI's deviation window, verify.DEV_WINDOW).
WINDOW = (-1.5, 0.5)


class SpectrumError(ParameterError):
    """The pulse has no usable unstable eigenmode (none stored or computable, not unstable, or a
    mode of another pulse)."""


@dataclass
class Eigenmode:
    """The leading eigenvalue of one pulse and its mode on the pulse's grid.

    Attributes
    ----------
    label : str
    sigma : complex
        Eigenvalue, 1/s (perturbations ∝ e^{σt} at fixed ξ = x − c_p t).
    rate_unit : float
        c_p/L, 1/s.
    xi : ndarray
        The pulse's grid, m.
    delta, V, phi, lnv : ndarray (complex)
        δ₁ (m), V₁ (m/s), φ₁ (s), y₁ = V₁/(v₀ + v*) (max |y₁| = 1).
    tau_d_ratio, L, c_p : float
        Of the pulse the mode belongs to.
    source : str
        Where the mode comes from ("stored in FILE" or "computed").
    translation_s_per_L : float
        The translation eigenvalue σ_t L/c_p (exact 0): the discretisation's error indicator.
    s_err_per_L : float
        The stored error of the growth rate (``steady stability``'s ladder of grids); NaN when
        the spectrum has none (computed on the fly, or stored without a ladder).
    """

    label: str
    sigma: complex
    rate_unit: float
    xi: np.ndarray
    delta: np.ndarray
    V: np.ndarray
    phi: np.ndarray
    lnv: np.ndarray
    tau_d_ratio: float
    L: float
    c_p: float
    source: str
    translation_s_per_L: float = math.nan
    s_err_per_L: float = math.nan

    @property
    def s_per_L(self) -> float:
        """Re σ L/c_p: e-folds per pulse length travelled."""
        return float(self.sigma.real / self.rate_unit)

    @property
    def is_real(self) -> bool:
        return abs(self.sigma.imag) <= REAL_TOL * abs(self.sigma.real)


def _from_stored(d: dict, label: str, source: str) -> Eigenmode:
    return Eigenmode(label=label, sigma=complex(d["sigma"][0]),
                     rate_unit=float(d["rate_unit_c_over_L"]), xi=np.asarray(d["xi"], float),
                     delta=d["delta"][0], V=d["V"][0], phi=d["phi"][0], lnv=d["lnv"][0],
                     tau_d_ratio=float(d["tau_d_ratio"]), L=float(d["L"]), c_p=float(d["c_p"]),
                     source=source,
                     translation_s_per_L=float(d.get("translation_s_per_L", math.nan)),
                     s_err_per_L=float(d.get("s_err_per_L", math.nan)))


def stored_mode(path: str, label: str) -> Eigenmode | None:
    """The leading mode stored in ``path`` for pulse ``label`` (``slippulse steady stability``),
    or None when there is none. A stored spectrum that failed, or holds no unstable eigenvalue,
    raises :class:`SpectrumError` naming the file."""
    from ..spectrum.pulse import read_spectrum
    try:
        d = read_spectrum(path, label)
    except (OSError, KeyError) as exc:
        raise SpectrumError(f"{path}: cannot read the spectrum of {label} ({exc})") from None
    if d is None:
        return None
    if d.get("status") != "converged":
        raise SpectrumError(f"{path}: the stored spectrum of {label} has status "
                            f"{d.get('status')!r} ({d.get('message', '')}); rerun "
                            "'slippulse steady stability --overwrite'")
    if d["sigma"].size == 0 or not d["sigma"][0].real > 0:
        raise SpectrumError(f"{path}: pulse {label} has no unstable eigenvalue stored "
                            f"({d.get('message', '')}): nothing to seed or compare with")
    return _from_stored(d, label, f"stored in {path}")


def computed_mode(pulse, params) -> Eigenmode:
    """The leading mode computed now (``spectrum.pulse_spectrum``, leading eigenvalue only).
    N = 2000: about a minute; the cost grows as N³."""
    from ..spectrum.pulse import pulse_spectrum
    if pulse.mode != "III":
        raise SpectrumError(f"pulse {pulse.label} is a mode-{pulse.mode} pulse: the spectrum "
                            "is for mode III")
    if not pulse.converged:
        raise SpectrumError(f"pulse {pulse.label} did not converge: it has no spectrum")
    res = pulse_spectrum(pulse, params, extra=False)
    if res.status != "converged":
        raise SpectrumError(f"the spectrum of {pulse.label} failed: {res.message}")
    if res.sigmas.size == 0 or not res.sigmas[0].real > 0:
        raise SpectrumError(f"pulse {pulse.label} has no unstable eigenvalue "
                            f"({res.message}): nothing to seed or compare with")
    m = res.modes[0]
    return Eigenmode(label=pulse.label, sigma=complex(res.sigmas[0]), rate_unit=res.rate_unit,
                     xi=np.asarray(pulse.xi, float), delta=m["delta"], V=m["V"], phi=m["phi"],
                     lnv=m["lnv"], tau_d_ratio=float(pulse.tau_d_ratio), L=float(pulse.L),
                     c_p=float(pulse.c_p), source="computed",
                     translation_s_per_L=float(res.neutral[1].real / res.rate_unit))


def leading_mode(pulse, params, path: str | None = None, mode_path: str | None = None,
                 compute: bool = True) -> Eigenmode:
    """The unstable eigenmode of ``pulse``: stored, else computed.

    Parameters
    ----------
    pulse, params
        The steady pulse (``h5io.read_pulse``).
    path : str, optional
        The pulse's file; its stored spectrum is used when present.
    mode_path : str, optional
        Another file to take the stored mode from (same label); it must belong to this pulse
        (:func:`check_same_pulse`), else :class:`SpectrumError`.
    compute : bool
        Compute the spectrum when none is stored (else :class:`SpectrumError`).
    """
    src = mode_path or path
    mode = stored_mode(src, pulse.label) if src else None
    if mode is None and mode_path:
        raise SpectrumError(f"{mode_path}: no spectrum stored for pulse {pulse.label} (run "
                            f"'slippulse steady stability {mode_path} --labels {pulse.label}')")
    if mode is None:
        if not compute:
            raise SpectrumError(f"{path}: no spectrum stored for pulse {pulse.label} (run "
                                f"'slippulse steady stability {path}')")
        mode = computed_mode(pulse, params)
    check_same_pulse(mode, pulse)
    return mode


def check_same_pulse(mode: Eigenmode, pulse) -> None:
    """Refuse a mode computed for another pulse: τ_d, c_p, L and the grid must be the pulse's."""
    why = None
    if abs(mode.tau_d_ratio - pulse.tau_d_ratio) > 1e-9:
        why = f"tau_d/tau_min {mode.tau_d_ratio:.6g} != {pulse.tau_d_ratio:.6g}"
    elif mode.xi.size != pulse.xi.size:
        why = f"grid of {mode.xi.size} points != {pulse.xi.size}"
    elif not np.allclose(mode.xi, pulse.xi, rtol=1e-12, atol=1e-12 * pulse.L):
        why = "the grids differ"
    elif abs(mode.c_p / pulse.c_p - 1) > 1e-9 or abs(mode.L / pulse.L - 1) > 1e-9:
        why = f"c_p or L differ ({mode.c_p:.8g}, {mode.L:.8g} m vs {pulse.c_p:.8g}, {pulse.L:.8g} m)"
    if why:
        raise SpectrumError(f"the mode ({mode.source}, {mode.label}) belongs to another pulse "
                            f"than {pulse.label}: {why}")


def check_eps(eps: float) -> float:
    """ε of a mode-seeded run: finite, nonzero, |ε| ≤ :data:`EPS_MAX` (the linear regime)."""
    eps = float(eps)
    if not (math.isfinite(eps) and 0 < abs(eps) <= EPS_MAX):
        raise ParameterError(f"eps={eps!r}: a mode perturbation needs 0 < |eps| <= {EPS_MAX:g} "
                             "(the linear regime: eps is the largest change of ln(v/v*+1))")
    return eps


# --------------------------------------------------------------------------- the SBI seed
def mode_on_grid(mode: Eigenmode, pulse, xi_grid):
    """The mode's relative fields V₁/v₀ and φ₁/φ₀ (real parts) at the SBI grid's ξ.

    The ratios are interpolated (PCHIP on the pulse's grid), not V₁ itself: near the steep front
    the mode carries a displacement, V₁ ≈ −η v₀′, whose ratio −η (ln v₀)′ is as smooth as ln v₀,
    the field the seed interpolates (``seeding.interpolate_log``).
    """
    rv = (mode.V.real / pulse.v)
    rphi = (mode.phi.real / pulse.phi)
    return (PchipInterpolator(pulse.xi, rv)(xi_grid), PchipInterpolator(pulse.xi, rphi)(xi_grid))


def perturb_along_mode(seed, mode: Eigenmode, eps: float, frame: str = "lab") -> None:
    """Perturb a seeded steady pulse along its unstable eigenmode, with a past that grew as e^{σt}.

    The seed (``seeding.seed_pulse`` of the unperturbed pulse) holds v₀, φ₀ translating at c
    forever. The perturbed past is, at fixed ξ = x − ct, for t ≤ 0,

        v = v₀(ξ) + ε V₁(ξ) e^{σt},  φ = φ₀ + ε φ₁ e^{σt},  δ = δ₀ + ε δ₁ e^{σt},

    i.e. in the lab frame a field g(x − ct) e^{σt}, whose Fourier mode k evolves as e^{(σ − ikc)t}.
    Hence (docs/stability.md §2): slip δ̂_k += ΔV̂_k/(σ − ikc) (k = 0 included: ΔV̂₀/σ), and
    the SOE accumulators get the past ∫₀^∞ e^{zωs} ΔV_k(−s) ds with ΔV_k(−s) = ΔV̂_k e^{−(σ−ikc)s}
    (``SOEHistory.prefill_translating(sigma=σ, add=True)``). The stress at t = 0 is then the
    steady stress plus K_σ[ε δ₁], the elastodynamic stress of the growing mode (the symbol
    −(μ/2)√(k² + (σ − ikc)²/c_s²) sampled at the period's k), which balances the linearised
    friction of the mode: the seed is the mode, not a generic perturbation.

    V = V₀ exp(ε V₁/v₀), φ = φ₀ exp(ε φ₁/φ₀) on the grid (positive for any ε; linear part ε V₁,
    ε φ₁). The far-field load stays the steady pulse's (it is static).

    ``frame="front"`` (docs/stability.md §2): ε is the largest change of y in the frame of the
    front, max |y₁ᶠ| (``front_response``), not max |y₁|, which near τ_min is the mode's front
    displacement (y₁ ≈ −η_R y₀′, 1850 times the body's change at 1.05 τ_min). The mode is
    split into its body and its displacement, V₁ = V₁ᶠ − η_R v₀′, and the displacement is
    carried exactly, as a translation: the past is the steady pulse on the trajectory
    X(t) = ct + A(t), A(t) = a(e^{σt} − 1), a = ε η_R (A(0) = 0: the front is where the steady
    seed put it), plus the body ε V₁ᶠ e^{σt} riding on it. In Fourier,
    e^{−ikA(t)} = e^{ika} Σ_n (−ika)^n e^{nσt}/n!, so the past is a sum of growing exponentials,
    each added to the slip and the SOE history as above (rates nσ and (n + 1)σ; the series is
    summed until its terms are below 1e−17 of the first). At t = 0: V = V₀ exp(ε V₁ᶠ/v₀),
    φ = φ₀ exp(ε φ₁ᶠ/φ₀), no displacement spike. To first order in ε this is the same seed
    as ``"lab"`` translated by a (an exact symmetry); beyond it the displacement is exact.
    """
    if frame not in ("lab", "front"):
        raise ValueError(f"frame={frame!r} must be 'lab' or 'front'")
    from ..dynamics.sbi import elastic_functional
    check_same_pulse(mode, seed.pulse)
    check_eps(eps)
    if not mode.is_real:
        raise SpectrumError(f"the leading eigenvalue of {mode.label} is complex "
                            f"({mode.sigma:.4g} 1/s): seeding needs a real one")
    if seed.stepper.history_name != "soe":
        raise ParameterError("a mode-seeded pulse needs the SOE history (it carries the past)")
    st = seed.stepper
    sigma = float(mode.sigma.real)
    c = float(seed.pulse.c_p)
    if frame == "front":
        _perturb_front_frame(seed, mode, eps, sigma, c)
        return
    rv, rphi = mode_on_grid(mode, seed.pulse, st.x - seed.xi_shift)
    V_new = st.V * np.exp(eps * rv)
    dV = V_new - st.V
    dVk = st.fft.forward(dV).copy()
    p = sigma - 1j * st.kabs * c
    st.V = V_new
    st.phi = st.phi * np.exp(eps * rphi)
    st.V_k = st.fft.forward(st.V).copy()
    st.delta_k = st.delta_k + dVk / p
    st.delta = st.fft.inverse(st.delta_k).copy()
    st.history.prefill_translating(dVk, st.kabs, c, sigma=sigma, add=True)
    f = st.fft.inverse(elastic_functional(st.params.mu, st.kabs, st.delta_k, st.history.value()))
    st.tau = st.law.tau_load - st.eta * st.V + f


def front_frame_seed_fields(mode: Eigenmode, pulse, v_star: float):
    """The mode split for the front-frame seed: (η, rv_f, rphi_f, scale) on the pulse's grid.

    η = η_R of :func:`front_response` per unit of the stored mode (m); rv_f = V₁ᶠ/v₀ =
    V₁/v₀ + η (ln v₀)′ and rphi_f = φ₁/φ₀ + η (ln φ₀)′, the body's relative fields; all three
    divided by ``scale`` = max |y₁ᶠ| (y₁ᶠ = y₁ + η y₀′), so that ε = 1 is a unit change of
    y = ln(v/v*+1) in the frame of the front."""
    fr = front_response(mode, pulse, v_star)
    eta = float(fr["eta_front"])
    scale = float(np.max(np.abs(fr["y1f"])))
    rv = fr["y1f"] * (pulse.v + v_star) / pulse.v        # V₁ᶠ/v₀ = y₁ᶠ (v₀ + v*)/v₀
    rphi = fr["psi1f"]                                    # φ₁ᶠ/φ₀ = ψ₁ + η ψ₀′
    return eta / scale, rv / scale, rphi / scale, scale


def _perturb_front_frame(seed, mode: Eigenmode, eps: float, sigma: float, c: float) -> None:
    """``perturb_along_mode(frame="front")``: the body with its growing past, the displacement
    as an exact translation of the past (see there)."""
    from ..dynamics.sbi import elastic_functional
    st = seed.stepper
    pulse = seed.pulse
    eta, rv, rphi, _ = front_frame_seed_fields(mode, pulse, seed.params.v_star)
    xg = st.x - seed.xi_shift
    rv_g = PchipInterpolator(pulse.xi, rv)(xg)
    rphi_g = PchipInterpolator(pulse.xi, rphi)(xg)
    a = eps * eta
    V0k = st.fft.forward(st.V).copy()
    V_new = st.V * np.exp(eps * rv_g)
    body_k = st.fft.forward(V_new - st.V).copy()
    k = st.kabs
    ph = np.exp(1j * k * a)
    terms = [(V0k * (ph - 1.0), 0.0)]                 # the far past: the pulse shifted by −a
    x = -1j * k * a
    coef = np.ones_like(x)
    n = 0
    while True:
        n += 1
        coef = coef * x / n                           # (−ika)^n / n!
        if n > 1 and np.max(np.abs(coef)) < 1e-17:
            break
        terms.append((V0k * ph * coef, n * sigma))
    coef = np.ones_like(x)
    terms.append((body_k * ph, sigma))
    n = 0
    while True:
        n += 1
        coef = coef * x / n
        if n > 1 and np.max(np.abs(coef)) < 1e-17:
            break
        terms.append((body_k * ph * coef, (n + 1) * sigma))
    dk = np.zeros_like(st.delta_k)
    for amp, rate in terms:
        p = rate - 1j * k * c
        with np.errstate(all="ignore"):
            d = np.where(p != 0, amp / np.where(p != 0, p, 1.0), 0.0)
        dk = dk + d
        st.history.prefill_translating(amp, k, c, sigma=rate, add=True)
    st.V = V_new
    st.phi = st.phi * np.exp(eps * rphi_g)
    st.V_k = st.fft.forward(st.V).copy()
    st.delta_k = st.delta_k + dk
    st.delta = st.fft.inverse(st.delta_k).copy()
    f = st.fft.inverse(elastic_functional(st.params.mu, st.kabs, st.delta_k, st.history.value()))
    st.tau = st.law.tau_load - st.eta * st.V + f


# ----------------------------------------------------------------------- the front frame
def _spline(xi, y):
    return CubicSpline(xi, y)


def front_response(mode: Eigenmode, pulse, v_star: float) -> dict:
    """The mode as a front-following observer (the SBI) sees it, per unit amplitude.

    With y = ln(v/v*+1), y = y₀ + A y₁ (A = ε e^{σt}), the half maximum h = max y/2 moves by
    A h₁, h₁ = y₁(ξ_max)/2 (y₀′ = 0 at the maximum), so each half-maximum crossing ξ_X moves by
    A η_X with

        η_X = (h₁ − y₁(ξ_X)) / y₀′(ξ_X)      (X = R: front, L: healing edge).

    The front moves at c_p + σ A η_R: δc/c_p = σ η_R/c_p; the pulse length changes by
    δL = η_R − η_L. At fixed distance ζ from the front the deviation is
    y₁ᶠ(ζ) = y₁(ξ_R + ζ) + η_R y₀′(ξ_R + ζ), and likewise ψ₁ᶠ for ψ = ln φ (ψ₁ = φ₁/φ₀): the
    translation is removed by pinning the front (the gauge the SBI measures in).

    Returns
    -------
    dict
        eta_front, eta_back (m), dL_over_L, dc_over_c, dvmax_over_vmax (V₁/v₀ at the peak:
        the relative change of v_max) (per unit A), direction (the slope
        (δc/c)/(δL/L) in the (ln L, ln c_p) plane), zeta (m, ξ − ξ_R on the pulse's grid),
        y1f, psi1f (front-frame fields), xi_front.
    """
    xi = pulse.xi
    y0 = np.log1p(pulse.v / v_star)
    y1 = mode.lnv.real
    psi0 = np.log(pulse.phi)
    psi1 = mode.phi.real / pulse.phi
    L, xl, xr = pulse_length(xi, pulse.v, v_star)
    k = int(np.argmax(y0))
    h1 = 0.5 * y1[k]
    sy0, sy1, sps0 = _spline(xi, y0), _spline(xi, y1), _spline(xi, psi0)
    eta_r = (h1 - float(sy1(xr))) / float(sy0(xr, 1))
    eta_l = (h1 - float(sy1(xl))) / float(sy0(xl, 1))
    dL = (eta_r - eta_l) / L
    dc = mode.sigma.real * eta_r / pulse.c_p
    zeta = xi - xr
    y1f = y1 + eta_r * sy0(xi, 1)
    psi1f = psi1 + eta_r * sps0(xi, 1)
    dvmax = float(mode.V.real[k] / pulse.v[k])
    return {"eta_front": eta_r, "eta_back": eta_l, "dL_over_L": dL, "dc_over_c": dc,
            "dvmax_over_vmax": dvmax,
            "direction": dc / dL if dL != 0 else math.copysign(math.inf, dc),
            "zeta": zeta, "y1f": y1f, "psi1f": psi1f, "xi_front": xr, "L": L}


def _front_fields(pulse, v_star, zeta):
    """y = ln(v/v*+1) and ψ = ln φ of a pulse at ζ = ξ − ξ_R (PCHIP on its grid)."""
    _, _, xr = pulse_length(pulse.xi, pulse.v, v_star)
    x = xr + zeta
    y = PchipInterpolator(pulse.xi, np.log1p(pulse.v / v_star))(x)
    psi = PchipInterpolator(pulse.xi, np.log(pulse.phi))(x)
    return y, psi


def family_tangent(pulse, neighbours, v_star, zeta):
    """d(y, ln φ)/dτ_d at fixed distance ζ from the front, and d ln L, d ln c_p per unit τ_d/τ_min.

    Parameters
    ----------
    pulse : Pulse
        The pulse at which the tangent is wanted (used for a one-sided difference).
    neighbours : list of Pulse
        One or two neighbouring pulses of the family: two give the central difference (second
        order on a non-uniform τ_d step: the derivative of the parabola through the three), one a
        one-sided difference.
    zeta : ndarray
        ξ − ξ_front (m) where the fields are compared.

    Returns
    -------
    dict
        ty, tpsi (per unit τ_d/τ_min), dlnL, dlnc (per unit τ_d/τ_min), slope = dlnc/dlnL (the
        steady line's direction in the (ln L, ln c_p) plane).
    """
    q0 = pulse.tau_d_ratio
    pts = [(q0, *_front_fields(pulse, v_star, zeta), math.log(pulse.L), math.log(pulse.c_p))]
    for nb in neighbours:
        pts.append((nb.tau_d_ratio, *_front_fields(nb, v_star, zeta), math.log(nb.L),
                    math.log(nb.c_p)))
    if len(pts) == 2:
        (qa, *a), (qb, *b) = pts
        w = [-1.0 / (qb - qa), 1.0 / (qb - qa)]
    elif len(pts) == 3:
        qa, qb, qc = pts[0][0], pts[1][0], pts[2][0]
        # derivative at qa of the Lagrange parabola through (qa, qb, qc)
        w = [(2 * qa - qb - qc) / ((qa - qb) * (qa - qc)), (qa - qc) / ((qb - qa) * (qb - qc)),
             (qa - qb) / ((qc - qa) * (qc - qb))]
    else:
        raise ValueError("family_tangent needs one or two neighbours")
    ty = sum(wi * p[1] for wi, p in zip(w, pts))
    tpsi = sum(wi * p[2] for wi, p in zip(w, pts))
    dlnL = sum(wi * p[3] for wi, p in zip(w, pts))
    dlnc = sum(wi * p[4] for wi, p in zip(w, pts))
    return {"ty": ty, "tpsi": tpsi, "dlnL": dlnL, "dlnc": dlnc, "slope": dlnc / dlnL}


def mode_overlap(zeta, m_fields, t_fields, L, window=WINDOW):
    """|⟨m, t⟩| / (‖m‖ ‖t‖) over ζ ∈ window·L, ⟨a, b⟩ = Σ_fields ∫ a b dζ (trapezoid on the
    pulse's non-uniform grid). 1 when the fields are proportional. m_fields, t_fields: tuples of
    arrays on ``zeta`` (e.g. (y₁ᶠ, ψ₁ᶠ) and (t_y, t_ψ))."""
    sel = (zeta >= window[0] * L) & (zeta <= window[1] * L)
    z = zeta[sel]

    def dot(a, b):
        return sum(float(np.trapezoid(ai[sel] * bi[sel], z)) for ai, bi in zip(a, b))

    mm, tt, mt = dot(m_fields, m_fields), dot(t_fields, t_fields), dot(m_fields, t_fields)
    if not (mm > 0 and tt > 0):
        return math.nan
    return abs(mt) / math.sqrt(mm * tt)


def pulse_overlap(pulse, mode, neighbours, v_star) -> dict:
    """Overlap of the front-frame mode and the family tangent at one pulse, and the mode's
    direction in the (ln L, ln c_p) plane against the steady line's.

    Returns a dict: overlap (y and ln φ), overlap_y (y only), the mode's dL_over_L, dc_over_c,
    direction (its slope d ln c/d ln L), line_slope (the family's), departure_per_dlnL =
    direction − line_slope (the first-order departure c_p/c_p⁰(L) − 1 per unit relative change
    of L: 0 on the line), departure_fraction = 1 − line_slope/direction (the part of the mode's
    change of ln c_p that is departure from the line: c_p/c_p⁰(L) − 1 ≈ f·δ ln c_p; 0 on the
    line, 1 when the mode changes c_p at fixed L), angle_deg (between the two directions in the
    (ln L, ln c_p) plane).
    """
    fr = front_response(mode, pulse, v_star)
    tg = family_tangent(pulse, neighbours, v_star, fr["zeta"])
    ov = mode_overlap(fr["zeta"], (fr["y1f"], fr["psi1f"]), (tg["ty"], tg["tpsi"]), pulse.L)
    ovy = mode_overlap(fr["zeta"], (fr["y1f"],), (tg["ty"],), pulse.L)
    a = np.array([fr["dL_over_L"], fr["dc_over_c"]])
    b = np.array([tg["dlnL"], tg["dlnc"]])
    cosang = abs(float(a @ b)) / float(np.linalg.norm(a) * np.linalg.norm(b))
    return {"tau_d_ratio": pulse.tau_d_ratio, "overlap": ov, "overlap_y": ovy,
            "dL_over_L": fr["dL_over_L"], "dc_over_c": fr["dc_over_c"],
            "direction": fr["direction"], "line_slope": tg["slope"],
            "departure_per_dlnL": fr["direction"] - tg["slope"],
            "departure_fraction": 1.0 - tg["slope"] * fr["dL_over_L"] / fr["dc_over_c"],
            "angle_deg": math.degrees(math.acos(min(1.0, cosang))),
            "s_per_L": mode.s_per_L}


def local_neighbours(pulse, params, h: float = 2e-3):
    """The pulses at τ_d/τ_min ± h solved on ``pulse``'s own grid from ``pulse`` (Newton, no
    regridding): the family tangent by a central difference of step h, free of the interpolation
    between the adapted grids of a coarse family (used where the family's step is too coarse for
    the tangent, near τ_min). Raises SpectrumError when a solve does not converge."""
    from ..steady.solver import solve_pulse
    out = []
    for q in (pulse.tau_d_ratio - h, pulse.tau_d_ratio + h):
        sol = solve_pulse(params, q, n_points=pulse.xi.size,
                          guess=(pulse.xi, np.log(pulse.v), pulse.beta), passes=0,
                          adapt_guess=False,
                          state_order=state_order_of(pulse))
        if not sol.stats.converged:
            raise SpectrumError(f"neighbour of {pulse.label} at tau_d/tau_min = {q:.6g} did not "
                                "converge on its grid")
        out.append(sol.to_pulse())
    return out


def family_overlaps(path: str, compute: bool = False, local_h: float | None = None,
                    labels=None) -> list[dict]:
    """:func:`pulse_overlap` at every converged pulse of a family file that has a stored
    spectrum (or, with ``compute``, a computable one), with its neighbours in τ_d as the tangent
    (or, with ``local_h``, the pulses at τ_d ± local_h solved on its grid,
    :func:`local_neighbours`). ``labels``: only these pulses."""
    from ..core.h5io import list_pulses, read_pulse
    pulses = []
    params = None
    for lab in list_pulses(path):
        pu, params = read_pulse(path, lab)
        if pu.converged and pu.mode == "III":
            pulses.append(pu)
    pulses.sort(key=lambda p: p.tau_d_ratio)
    out = []
    for i, pu in enumerate(pulses):
        if labels and pu.label not in labels:
            continue
        try:
            mode = leading_mode(pu, params, path=path, compute=compute)
        except SpectrumError:
            continue
        if local_h:
            nb = local_neighbours(pu, params, local_h)
        else:
            nb = [pulses[j] for j in (i - 1, i + 1) if 0 <= j < len(pulses)]
        if not nb:
            continue
        row = pulse_overlap(pu, mode, nb, params.v_star)
        row["label"] = pu.label
        out.append(row)
    return out
