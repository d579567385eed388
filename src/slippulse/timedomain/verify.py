"""Propagate a seeded steady pulse and measure its drift from the steady solution.

``verify_pulse`` seeds the SBI stepper with a steady pulse (:mod:`slippulse.timedomain.seeding`), steps it over
a given number of pulse lengths with adaptive time steps, keeps it in a frame that follows it
(``seeding.follow_pulse``) and measures, in the co-moving frame:

* c_p(t)/c_p⁰ − 1: c_p(t) = ΔX/Δt of the front position X (the front half-maximum crossing of
  ln(v/v*+1), located to a fraction of a cell by a local cubic, ``analysis.pulse_length``) over
  the last sampling interval; the end-of-run value ``c_p_error`` is the mean speed over the last
  quarter of the run;
* v_max(t)/v_max⁰ − 1: v_max from a parabola through ln v at the three points around the maximum;
* L(t)/L⁰ − 1: L, the FWHM of ln(v/v*+1) (``analysis.pulse_length``);
* the relative L2 error of y = ln(v/v*+1) over the pulse, ‖y − y⁰‖₂/‖y⁰‖₂ on the grid points with
  ξ − ξ_front ∈ [−1.25 L⁰, 0.25 L⁰], y⁰ the steady profile shifted onto the measured front (so it
  measures shape, not position: position errors are in c_p).

The references c_p⁰ and L⁰ are the steady file's values; v_max⁰ is the parabolic peak of the
steady profile (:func:`reference_v_max`; the file's v_max is the largest node value).
``write_result`` stores the final errors as root attributes and their time series; ``slippulse.plotting.stability.plot_verify_result``
draws v(ξ) at several times over the steady profile. CLI: ``slippulse dynamic verify`` (cli/dynamic.py).
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.interpolate import PchipInterpolator

from ..core.params import DEFAULT
from ..steady.measures import pulse_length
from .seeding import DomainSpec, SeededPulse, follow_pulse, seed_pulse
from ..dynamics.stepper import TimeStepRule

#: Window of the ln v error, in steady pulse lengths relative to the front crossing.
LNV_WINDOW = (-1.25, 0.25)
SERIES = ("c_p_error", "v_max_error", "L_error", "lnv_error")
#: Other series written by :func:`write_result`, with units.
EXTRA_SERIES = {"L": "m", "v_max": "m/s", "slip": "m", "distance": "1", "c_p": "m/s",
                "potency_rate": "m^2/s", "slip_potency": "m^2"}
#: Window and sampling of the stored deviation field y − y⁰ (in L⁰ relative to the front).
DEV_WINDOW = (-1.5, 0.5)
DEV_POINTS = 201
PERTURBATIONS = ("excess", "tau_d", "mode", "mode_front")
#: The mode-seeded kinds and the frame in which their ε is measured (eigenmode.perturb_along_mode).
MODE_FRAMES = {"mode": "lab", "mode_front": "front"}


class PulseLost(RuntimeError):
    """The pulse left the steady neighbourhood (grew into a crack or arrested)."""


def growth_rate(distance, err, lo=3e-4, hi=3e-2):
    """Exponential growth rate of |err| per pulse length travelled, least squares in ln|err|.

    Uses the samples with lo ≤ |err| ≤ hi (above the start-up level, below saturation); NaN when
    fewer than 3 qualify. (Measured at 1.2 τ_min, Δx = 2 mm: 22.2 and 22.9 per L for ξ_s = 0.5 and
    0.25; a window starting at 3e-5 mixes in the start-up and gave 19.4 and 24.2.)
    """
    d, e = np.asarray(distance), np.abs(np.asarray(err))
    sel = (e >= lo) & (e <= hi) & np.isfinite(e)
    if sel.sum() < 3:
        return float("nan")
    return float(np.polyfit(d[sel], np.log(e[sel]), 1)[0])


@dataclass
class VerifyResult:
    """Time series and end-of-run errors of a verification run."""

    t: np.ndarray
    x_front: np.ndarray
    series: dict
    errors: dict
    info: dict
    snapshots: list = field(default_factory=list)   # (t, ξ − ξ_front, V)
    x: np.ndarray | None = None                      # the SBI grid of the snapshots (m)


def front_position(x, V, v_star):
    """Front half-maximum crossing of y = ln(V/v* + 1) on a uniform grid, and y's maximum.

    Returns (x_front, L, v_max): x_front and L as in ``analysis.pulse_length``; v_max from the
    parabola through ln V at the maximum and its two neighbours (periodic indices).
    """
    L, _, xr = pulse_length(x, V, v_star)
    i = int(np.argmax(V))
    n = V.size
    a, b, c = np.log(V[(i - 1) % n]), np.log(V[i]), np.log(V[(i + 1) % n])
    den = a - 2.0 * b + c
    vmax = math.exp(b - 0.125 * (c - a) ** 2 / den) if den < 0 else float(V[i])
    return xr, L, vmax


def reference_v_max(xi, v):
    """Peak slip rate of a sampled profile: the vertex of the parabola through ln v at the largest
    sample and its two neighbours (non-uniform abscissae allowed), m/s.

    The steady files store v_max = max over the nodes, which at 1.05 τ_min is 7e-5 below the
    peak between nodes (N = 3000); comparing the SBI's parabolic peak with it would bias v_max_error
    by that much at any resolution.
    """
    i = int(np.argmax(v))
    if i == 0 or i == v.size - 1:
        return float(v[i])
    x = np.asarray(xi[i - 1:i + 2], dtype=float) - xi[i]
    c2, c1, c0 = np.polyfit(x, np.log(v[i - 1:i + 2]), 2)
    return float(math.exp(c0 - c1 * c1 / (4 * c2))) if c2 < 0 else float(v[i])


def measure(seed: SeededPulse, steady_y, xi_front_steady):
    """Front position (unwrapped, m), L (m), v_max (m/s) and the ln v error of the current state."""
    st, pulse, p = seed.stepper, seed.pulse, seed.params
    xr, L, vmax = front_position(st.x, st.V, p.v_star)
    rel = st.x - xr
    lo, hi = LNV_WINDOW[0] * pulse.L, LNV_WINDOW[1] * pulse.L
    sel = (rel >= lo) & (rel <= hi)
    y = np.log1p(st.V[sel] / p.v_star)
    y0 = steady_y(xi_front_steady + rel[sel])
    err = float(np.linalg.norm(y - y0) / np.linalg.norm(y0))
    return xr + seed.shift_cells * st.dx, L, vmax, err


def perturbed_pulse(pulse, kind: str, eps: float):
    """The pulse to seed for a perturbation ``kind`` of size ``eps`` (:func:`perturb_seed`)."""
    if kind not in PERTURBATIONS:
        raise ValueError(f"perturbation={kind!r} must be one of {PERTURBATIONS}")
    if not (math.isfinite(eps) and abs(eps) < 0.5):
        raise ValueError(f"eps={eps!r} must satisfy |eps| < 0.5")
    if kind in MODE_FRAMES:            # seeded unperturbed, then eigenmode.perturb_along_mode
        from .eigenmode import check_eps
        check_eps(eps)
        return pulse
    if kind == "excess":
        v = pulse.v + eps * np.maximum(pulse.v - pulse.v_stick, 0.0)
        return replace(pulse, v=v)
    return pulse


def perturb_seed(seed: SeededPulse, pulse, kind: str, eps: float) -> None:
    """Finish a perturbed seed and restore the unperturbed pulse as the reference.

    ``"excess"``: the seed was built from v' = v + ε·max(v − v_stick, 0) — the slip-rate excess
    scaled by 1 + ε where the interface slips faster than creep, so v' > 0 for ε > −1 — with
    the slip, history and far-field load of v' translating at c_p forever (the state φ is the
    steady one). The friction law then picks the slip rate consistent with that stress and state:
    a perturbation of slip rate, slip and stress at once, of relative size ε.

    ``"tau_d"``: the unperturbed seed with the driving stress raised by ε·τ_d everywhere
    (τ_load0 and the current load): the pulse is off its steady state by the neighbour pulse at
    τ_d(1 + ε); far ahead the creep at v_stick is slightly out of balance too (a uniform
    acceleration of order ε·τ_d/(σ a) relative).
    """
    if kind == "tau_d":
        dtau = eps * pulse.tau_d
        seed.tau_load0 += dtau
        seed.stepper.law.tau_load = seed.stepper.law.tau_load + dtau
    seed.pulse = pulse


def slip_across(st, x_front, L):
    """δ(x_front − 1.5 L) − δ(x_front + 0.5 L) on the periodic grid (linear interpolation), m."""
    xs = np.array([x_front - 1.5 * L, x_front + 0.5 * L]) % st.length
    d = np.interp(xs, np.r_[st.x, st.length], np.r_[st.delta, st.delta[0]])
    return float(d[0] - d[1])


def steady_slip(pulse, xi_front):
    """The same slip for the isolated steady pulse: ∫(v − v_stick)dξ/c_p over [ξ_R − 1.5L, ξ_R + 0.5L]."""
    sel = (pulse.xi >= xi_front - 1.5 * pulse.L) & (pulse.xi <= xi_front + 0.5 * pulse.L)
    return float(np.trapezoid(pulse.v[sel] - pulse.v_stick, pulse.xi[sel]) / pulse.c_p)


def deviation_field(st, x_front, steady_y, xi_front, rel, v_star):
    """y − y⁰ at ξ − ξ_front = ``rel`` (linear interpolation of the grid's y = ln(V/v*+1))."""
    xs = (x_front + rel) % st.length
    y = np.interp(xs, np.r_[st.x, st.length], np.log1p(np.r_[st.V, st.V[0]] / v_star))
    return y - steady_y(xi_front + rel)


def potency_rate(st) -> float:
    """Σ V Δx over the whole periodic grid, m²/s.

    A functional Σ g(V_i) Δx does not see the frame: a whole-cell shift of the frame permutes
    the periodic grid, and there is no interpolation. In a ±ε pair seeded with the mode
    (δ₁, V₁) its antisymmetric part is ε e^{σt} ∫ V₁ dξ + O(ε³) = ε e^{σt} σ ∫ δ₁ dξ: the
    mode's translation part (−η v₀′) drops out (∫ v₀′ dξ = 0), so it measures the pulse body's
    response (docs/stability.md §2). (Σ ln(V/v*+1) Δx was tried too: it weights the creeping
    tail, where the frame's reset of the entering cells acts, and was noisier.)"""
    return float(np.sum(st.V) * st.dx)


def _lost_how(st, pulse) -> str:
    """'grew' or 'arrested': the direction in which a pulse whose FWHM cannot be measured left."""
    return "grew" if float(st.V.max()) > pulse.v_max else "arrested"


@dataclass(frozen=True)
class VerifySettings:
    """How a verification run is made (the options of :func:`verify_pulse`, stored in its
    ``info``).

    Attributes
    ----------
    rule : TimeStepRule, optional
        Default adaptive, β_cfl = 0.5, ξ = 0.1, ξ_s = 0.5.
    far_field : {"steady", "none"}
        See ``seeding.seed_pulse`` ("steady" requires ``follow``).
    history_start : {"steady", "rest"}
        See ``seeding.seed_pulse`` ("rest": a history started at t = 0, for the failure map).
    history : {"soe", "quasi_dynamic"}
        See ``seeding.seed_pulse`` ("quasi_dynamic": radiation damping only, failure map).
    wrap_dislocation : bool
        Leave the wrap dislocation in the seeded slip (failure map; ``seeding.seed_pulse``).
    follow : bool
        Shift the frame by whole cells to keep the pulse in place (``seeding.follow_pulse``).
    n_samples : int
        Measurements (evenly spaced in time).
    n_snapshots : int
        Stored slip-rate profiles (evenly spaced in time, t = 0 included).
    track_every : int
        Steps between front measurements that move the frame and the far-field load
        (the front moves ≈ Δx/70 per adaptive step at 1.2 τ_min).
    lost_factor : float
        Stop once max V exceeds lost_factor·v_max⁰ (status "pulse lost: grew ..."), falls below
        v_max⁰/lost_factor ("pulse lost: arrested ..."), or when the FWHM can no longer be
        measured (grew or arrested by the sign of v_max − v_max⁰).
    perturbation : (kind, ε), optional
        Start from a perturbed pulse (:func:`perturb_seed`): ``("excess", ε)`` scales the slip-rate
        excess by 1 + ε, ``("tau_d", ε)`` raises the driving stress by ε·τ_d, ``("mode", ε)`` adds
        ε × the unstable eigenmode (:func:`verify_pulse`'s ``eigen``) with its growing past
        (``eigenmode.perturb_along_mode``; 0 < |ε| ≤ ``eigenmode.EPS_MAX``), ``("mode_front", ε)``
        the same mode with ε measured in the frame of the front and the front's displacement
        carried exactly (``frame="front"``). The errors are still
        measured against the unperturbed steady pulse.
    device : {"cpu", "cupy", "numpy"}
        Where the steps run after seeding: "cpu" the host stepper; "cupy" a GPU
        (``dynamics.device.DeviceStepper``, same scheme); "numpy" the device engine on the host
        (bit-identical to "cpu"; for tests).
    history_options : dict, optional
        SOE options of the seeded stepper (``seeding.seed_pulse``).
    threads : int
        FFTW and numba threads of the stepper.
    """

    rule: TimeStepRule | None = None
    far_field: str = "steady"
    follow: bool = True
    n_samples: int = 100
    n_snapshots: int = 6
    history_options: dict | None = None
    threads: int = 1
    track_every: int = 4
    lost_factor: float = 20.0
    history_start: str = "steady"
    history: str = "soe"
    wrap_dislocation: bool = False
    perturbation: tuple | None = None
    device: str = "cpu"

    def __post_init__(self):
        if self.far_field == "steady" and not self.follow:
            raise ValueError("far_field='steady' is attached to the frame: it needs follow=True")


def verify_pulse(pulse, params, distance: float, spec: DomainSpec = DomainSpec(),
                 settings: VerifySettings | None = None, eigen=None, stop_check=None,
                 progress: bool = True) -> VerifyResult:
    """Seed ``pulse`` and propagate it over ``distance`` steady pulse lengths.

    Parameters
    ----------
    pulse, params
        Steady pulse and its parameters (``h5io.read_pulse``).
    distance : float
        Distance to travel, in pulse lengths L⁰ (run time t_end = distance·L⁰/c_p⁰).
    spec : DomainSpec
        Grid spacing and domain; with ``follow=False`` the travel distance is added ahead.
    settings : VerifySettings
        The run's options (default: ``VerifySettings()``; each is described there).
    eigen : eigenmode.Eigenmode, optional
        The pulse's unstable eigenmode (``eigenmode.leading_mode``): required by ``("mode", ε)``;
        its eigenvalue goes into ``info`` (:func:`eigen_info`) and is what :func:`drift_verdict`
        compares the drift with.
    stop_check : callable, optional
        ``stop_check(rows) -> str | None``, called after each measurement with the list of rows
        (t, X, L, v_max, lnv_error, slip); a string ends the run with that status (e.g. the
        deviation has grown past the linear regime).
    progress : bool
        tqdm bar on stderr (refresh ≥ 0.5 s on a terminal, 10 s otherwise).

    Returns
    -------
    VerifyResult
    """
    s = settings if settings is not None else VerifySettings()
    if not distance > 0:
        raise ValueError(f"distance={distance!r} must be > 0 (pulse lengths)")
    if not s.follow:
        spec = DomainSpec(dx=spec.dx, ahead=spec.ahead, behind=spec.behind, travel=distance)
    wall0 = time.perf_counter()
    seed = _seed_run(pulse, params, spec, s, eigen)
    # run: step to t_end = distance·L⁰/c_p⁰, sampling n_samples times
    rec = _Recorder(seed, pulse, params, distance, s.n_samples, s.n_snapshots)
    status = _run(seed, pulse, params, rec, s.follow, s.track_every, s.lost_factor, stop_check,
                  progress)
    wall = time.perf_counter() - wall0
    # measure: the errors against the steady pulse, their series and the run's description
    series, errors, (t, X, slip) = _measure(rec, pulse)
    info = _run_info(seed, pulse, params, spec, s, distance, status, wall, series, X, slip)
    if eigen is not None:
        info.update(eigen_info(eigen))
    # write: the caller stores the result (write_result) and draws it (plotting.stability)
    return VerifyResult(t=t, x_front=X, series=series, errors=errors, info=info,
                        snapshots=rec.snapshots, x=seed.stepper.x.copy())


def _seed_run(pulse, params, spec: DomainSpec, s: VerifySettings, eigen):
    """The run's start: the steady (or perturbed) pulse seeded as if it had travelled forever,
    on the settings' device."""
    perturbation = s.perturbation
    seed = seed_pulse(pulse if perturbation is None else perturbed_pulse(pulse, *perturbation),
                      params, spec, rule=s.rule, far_field=s.far_field,
                      history_options=s.history_options, threads=s.threads,
                      history_start=s.history_start, history=s.history,
                      wrap_dislocation=s.wrap_dislocation)
    if perturbation is not None and perturbation[0] in MODE_FRAMES:
        from .eigenmode import perturb_along_mode
        if eigen is None:
            raise ValueError("perturbation ('mode', eps) needs the pulse's eigenmode (eigen=)")
        perturb_along_mode(seed, eigen, float(perturbation[1]), frame=MODE_FRAMES[perturbation[0]])
    elif perturbation is not None:
        perturb_seed(seed, pulse, *perturbation)
    if s.device != "cpu":
        from ..dynamics.device import DeviceStepper
        seed.stepper = DeviceStepper.from_host(seed.stepper, s.device)
    return seed


def _run_info(seed, pulse, params, spec, s: VerifySettings, distance, status, wall, series, X,
              slip) -> dict:
    """The run's description stored with it: status, growth rates of the errors, cost, grid,
    settings, the steady pulse's measures and the errors at t = 0."""
    st = seed.stepper
    perturbation = s.perturbation
    dist = (X - X[0]) / pulse.L
    return {"status": status,
            "growth_rate_v_max": growth_rate(dist, series["v_max_error"]),
            "growth_rate_lnv": growth_rate(dist, series["lnv_error"]),
            "wall_time": wall, "n_steps": st.nstep, "t_end": float(st.t),
            "distance": float(distance), "travelled": float((X[-1] - X[0]) / pulse.L),
            "n": st.n, "length": st.length, "dx": st.dx, "ahead": spec.ahead,
            "behind": spec.behind, "far_field": s.far_field, "follow": bool(s.follow),
            "history_start": s.history_start, "history": s.history, "device": s.device,
            "wrap_dislocation": bool(s.wrap_dislocation),
            "perturbation": "none" if perturbation is None else str(perturbation[0]),
            "eps": 0.0 if perturbation is None else float(perturbation[1]),
            "slip0": float(slip[0]),
            "shift_cells": seed.shift_cells, "tau_d_ratio": pulse.tau_d_ratio,
            "table_I": bool(params == DEFAULT),
            "beta": pulse.beta, "c_p": pulse.c_p, "L": pulse.L, "v_max": pulse.v_max,
            "v_max_ref": reference_v_max(pulse.xi, pulse.v),
            "beta_cfl": st.rule.beta_cfl, "xi": st.rule.xi, "xi_stab": st.rule.xi_stab,
            "t0_v_max_error": float(series["v_max_error"][0]),
            "t0_L_error": float(series["L_error"][0]), "t0_lnv_error": float(series["lnv_error"][0])}


class _Recorder:
    """The measurements of a verification run: one row (t, X, L, v_max, lnv_error, slip) and one
    deviation profile per sample time t_j = j t_end/n_samples, slip-rate snapshots at some of them."""

    def __init__(self, seed, pulse, params, distance, n_samples, n_snapshots):
        self.seed, self.pulse, self.v_star = seed, pulse, params.v_star
        _, _, self.xi_front = pulse_length(pulse.xi, pulse.v, params.v_star)
        self.steady_y = PchipInterpolator(pulse.xi, np.log1p(pulse.v / params.v_star))
        self.t_end = distance * pulse.L / pulse.c_p
        self.t_samp = np.linspace(0.0, self.t_end, n_samples + 1)
        self.t_snap = set(np.round(np.linspace(0, n_samples, n_snapshots)).astype(int))
        self.n_samples = n_samples
        self.rows, self.devs, self.snapshots, self.potency = [], [], [], []
        self.slip_potency = []
        self.rel_dev = np.linspace(DEV_WINDOW[0], DEV_WINDOW[1], DEV_POINTS) * pulse.L
        self.slip_fix = 0.0

    def record(self, j):
        """Sample j: front X, FWHM L, v_max and the ln v error; the slip across the pulse (offset
        so that sample 0 equals the steady slip: the periodic slip's uniform gradient is constant,
        seeding.periodic_slip); the deviation profile; a snapshot when j is a snapshot index."""
        seed, pulse, st = self.seed, self.pulse, self.seed.stepper
        X, L, vmax, err = measure(seed, self.steady_y, self.xi_front)
        xr = X - seed.shift_cells * st.dx
        raw = slip_across(st, xr, pulse.L)
        if j == 0:
            self.slip_fix = steady_slip(pulse, self.xi_front) - raw
        self.rows.append((st.t, X, L, vmax, err, raw + self.slip_fix))
        self.devs.append(deviation_field(st, xr, self.steady_y, self.xi_front, self.rel_dev,
                                         self.v_star))
        self.potency.append(potency_rate(st))
        self.slip_potency.append(st.slip_potency())
        if j in self.t_snap:
            self.snapshots.append((st.t, st.x - xr, st.V.copy()))


def _run(seed, pulse, params, rec: _Recorder, follow, track_every, lost_factor, stop_check,
         progress) -> str:
    """Step the seeded pulse to rec.t_end, sampling at the first step past each t_j, moving the
    frame every ``track_every`` steps, stopping when the pulse is lost; returns the status."""
    from tqdm import tqdm

    st, t_end = seed.stepper, rec.t_end
    # cells behind and ahead of the peak in which the front is measured (3 L and 1 L)
    window = (math.ceil(3.0 * pulse.L / st.dx), math.ceil(1.0 * pulse.L / st.dx))
    rec.record(0)
    bar = tqdm(total=t_end, unit="s", disable=not progress, file=sys.stderr,
               mininterval=0.5 if sys.stderr.isatty() else 10.0,
               bar_format="{l_bar}{bar}| t={n:.4g}/{total:.4g} s [{elapsed}<{remaining}{postfix}]")
    j = 1
    status = "finished"
    try:
        while j <= rec.n_samples:
            dt = st.step()        # adaptive Δt; samples are taken at the first step past t_j
            bar.update(min(dt, max(t_end - bar.n, 0.0)))
            if follow and st.nstep % track_every == 0:
                try:
                    try:     # the window around the peak holds both crossings unless the pulse
                        xr, _, _ = front_position(*st.peak_window(*window), params.v_star)
                    except ValueError:    # has grown past it: then the whole ring
                        xr, _, _ = front_position(st.x, st.V, params.v_star)
                except ValueError as exc:
                    raise PulseLost(f"{_lost_how(st, pulse)}: {exc} at t = {st.t:.4g} s") from None
                follow_pulse(seed, xr)
            vtop = st.v_max()
            if vtop > lost_factor * pulse.v_max:
                raise PulseLost(f"grew: max V > {lost_factor:g} v_max0 at t = {st.t:.4g} s")
            if vtop < pulse.v_max / lost_factor:
                raise PulseLost(f"arrested: max V < v_max0/{lost_factor:g} at t = {st.t:.4g} s")
            if st.t >= rec.t_samp[j] * (1 - 1e-12):
                try:
                    rec.record(j)
                except ValueError as exc:
                    # the FWHM no longer exists on both sides of the maximum
                    raise PulseLost(f"{_lost_how(st, pulse)}: {exc} at t = {st.t:.4g} s") from None
                if stop_check is not None:
                    why = stop_check(rec.rows)
                    if why:
                        status = f"stopped: {why}"
                        break
                if follow:
                    follow_pulse(seed, rec.rows[-1][1] - seed.shift_cells * st.dx)
                bar.set_postfix_str(f"{st.nstep} steps, dt={dt:.3g} s", refresh=False)
                j += 1
    except FloatingPointError as exc:
        status = f"failed: {exc}"
    except PulseLost as exc:
        status = f"pulse lost: {exc}"
    finally:
        bar.close()
    return status


def _measure(rec: _Recorder, pulse):
    """Series and final errors of a run: c_p error from the front's travel (last quarter of the
    run for the final value, whole run for the mean), v_max error against the spline maximum of the
    steady profile, L error, ln v error. Returns (series, errors, (t, X, slip))."""
    arr = np.array(rec.rows)
    t, X, L, vmax, lnv, slip = arr.T
    cp = np.full_like(t, np.nan)
    cp[1:] = np.diff(X) / np.diff(t) / pulse.c_p - 1.0
    v_max0 = reference_v_max(pulse.xi, pulse.v)
    series = {"c_p_error": cp, "v_max_error": vmax / v_max0 - 1.0,
              "L_error": L / pulse.L - 1.0, "lnv_error": lnv,
              "L": L, "v_max": vmax, "slip": slip, "distance": (X - X[0]) / pulse.L,
              "c_p": np.r_[np.nan, np.diff(X) / np.diff(t)] if t.size > 1 else np.array([np.nan]),
              "deviation": np.array(rec.devs), "deviation_xi": rec.rel_dev / pulse.L}
    if rec.potency:
        series["potency_rate"] = np.array(rec.potency)
    if rec.slip_potency:
        series["slip_potency"] = np.array(rec.slip_potency)
    q = min(max(1, (t.size - 1) // 4), t.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cp_end = (X[-1] - X[-1 - q]) / (t[-1] - t[-1 - q]) / pulse.c_p - 1.0 if q > 0 else np.nan
        cp_mean = (X[-1] - X[0]) / (t[-1] - t[0]) / pulse.c_p - 1.0 if q > 0 else np.nan
    errors = {"c_p_error": float(cp_end),
              "v_max_error": float(series["v_max_error"][-1]),
              "L_error": float(series["L_error"][-1]),
              "lnv_error": float(lnv[-1]),
              "c_p_mean_error": float(cp_mean)}
    return series, errors, (t, X, slip)


#: Relative band within which a measured growth rate counts as the mode's: the verify runs are
#: short single runs seeded with the steady pulse, whose drift starts with a transient of the
#: other modes (docs/stability.md §3: +4 % at 1.2 τ_min with the plateau rule).
GROWTH_TOLERANCE = 0.25


def eigen_info(mode) -> dict:
    """The info entries of a run that describe its pulse's unstable eigenvalue
    (``eigenmode.Eigenmode``): eigen_s_per_L, eigen_sigma (1/s), eigen_source,
    eigen_translation_s_per_L (the error indicator, exact 0), eigen_s_err_per_L (the stored
    error of the rate, NaN when there is none)."""
    return {"eigen_s_per_L": float(mode.s_per_L), "eigen_sigma": float(mode.sigma.real),
            "eigen_source": str(mode.source),
            "eigen_translation_s_per_L": float(mode.translation_s_per_L),
            "eigen_s_err_per_L": float(getattr(mode, "s_err_per_L", math.nan))}


def mode_growth(info: dict):
    """(s, s_err, how) of the run's pulse's unstable mode, s per L⁰, or None.

    s is the leading eigenvalue of the linearised problem about the pulse the run seeded
    (docs/spectrum.md), stored in the run's info by :func:`verify_pulse` (``eigen=``, from the
    pulse's spectrum group or computed on the fly, ``eigenmode.leading_mode``); s_err is the
    stored error of the rate (the ladder of grids of ``steady stability``) where there is one,
    else the translation eigenvalue's size (exact 0: the discretisation's error indicator; NaN if
    unknown); ``how`` says where s and s_err came from. None when the run carries no
    eigenvalue. No table of measured rates: any τ_d.
    """
    s = info.get("eigen_s_per_L")
    if s is None or not math.isfinite(float(s)):
        return None
    stored = float(info.get("eigen_s_err_per_L", math.nan))
    err = stored if math.isfinite(stored) else abs(
        float(info.get("eigen_translation_s_per_L", math.nan)))
    return float(s), err, f"eigenvalue, {info.get('eigen_source', '?')}"


def drift_verdict(res: VerifyResult):
    """Is the drift of v_max the growth e^{s d} of the pulse's unstable mode?

    Returns ``(verdict, text)``: verdict True (the measured growth rate of |v_max error| per L⁰,
    :func:`growth_rate`, is within :data:`GROWTH_TOLERANCE` of the pulse's eigenvalue s,
    :func:`mode_growth`, and the mode grows by more than e over the run), False (it is not), or
    None (no eigenvalue known, the pulse stable, the mode grows by less than e over the run, too few samples to fit a rate, or a run
    that ended before its third measurement).
    ``text`` says which, in one clause.
    """
    i = res.info
    known = mode_growth(i)
    s_meas = i.get("growth_rate_v_max", float("nan"))
    if known is None:
        return None, ("no eigenvalue of the pulse's unstable mode is known (no stored spectrum "
                      "and none computed): drift not attributed")
    sv, err, how = known
    efolds = sv * i["travelled"]
    pm = (f" ± {err:.1g}" + ("" if math.isfinite(float(i.get("eigen_s_err_per_L", math.nan)))
                             else " (the translation eigenvalue's size)")
          if math.isfinite(err) else " (no error estimate)")
    mode = f"unstable mode s = {sv:.4g}{pm} per L ({how})"
    if i["status"] != "finished" and res.t.size < 3:
        return None, (f"the run ended after {res.t.size} measurement(s) ({i['status']}): too "
                      f"few to compare with the {mode}")
    agrees = (math.isfinite(s_meas) and abs(s_meas - sv)
              <= GROWTH_TOLERANCE * abs(sv) + (err if math.isfinite(err) else 0.0))
    if efolds < 1.0:
        # too short to attribute either way; say what the samples show (the figure draws them
        # against e^(s d)) rather than deny the growth
        seen = (f"|v_max error| grows as e^({s_meas:.3g} d), as the {mode} would" if agrees else
                f"|v_max error| grows as e^({s_meas:.3g} d), not as the {mode}" if
                math.isfinite(s_meas) else
                f"too few samples to fit a growth rate to compare with the {mode}")
        return None, (f"{seen}; but the mode grows by only e^{efolds:.2f} over "
                      f"{i['travelled']:.3g} L, too little to attribute the drift (a longer "
                      "run would)")
    if not math.isfinite(s_meas):
        return None, f"too few samples to fit a growth rate to compare with the {mode}"
    if agrees:
        return True, (f"|v_max error| grows as e^({s_meas:.3g} d), consistent with the {mode}: "
                      "the pulse's physical instability, not a numerical error")
    return False, (f"|v_max error| grows as e^({s_meas:.3g} d), NOT consistent with the {mode}")


def summary(res: VerifyResult) -> str:
    """One line: the four end-of-run errors, distance, steps, wall time, and whether the drift is
    the growth of the unstable mode (:func:`drift_verdict`)."""
    e, i = res.errors, res.info
    return (f"verify td{i['tau_d_ratio']:.4f}: {i['status']}; travelled {i['travelled']:.3f} L in "
            f"{i['n_steps']} steps ({i['wall_time']:.1f} s wall, N={i['n']}, dx={i['dx'] * 1e3:.3g} mm); "
            f"c_p_error={e['c_p_error']:.2e} v_max_error={e['v_max_error']:.2e} "
            f"L_error={e['L_error']:.2e} lnv_error={e['lnv_error']:.2e} (one run at one dx: "
            f"no error estimate of these); drift: {drift_verdict(res)[1]}")


#: long_name of every series written by :func:`write_result`.
SERIES_LONG_NAMES = {
    "x_front": "front position (half-maximum crossing of ln(v/v*+1)), unwrapped",
    "c_p_error": "c_p/c_p0 - 1 over the last sampling interval",
    "v_max_error": "v_max/v_max0 - 1", "L_error": "L/L0 - 1",
    "lnv_error": "relative L2 error of ln(v/v*+1) over the pulse",
    "L": "pulse length (FWHM of ln(v/v*+1))", "v_max": "peak slip rate",
    "slip": "slip across the pulse", "distance": "distance travelled, in steady pulse lengths L0",
    "c_p": "pulse speed over the last sampling interval",
    "potency_rate": "sum of V dx over the periodic grid (frame-free)",
    "slip_potency": "sum of slip dx over the periodic grid (frame-free; the time integral of "
                    "potency_rate as the scheme steps it)",
}


def write_result(path: str, res: VerifyResult, params, source: str = "", label: str = "",
                 steady_converged: bool = True) -> None:
    """Write the errors (root attributes), their time series and the snapshots to HDF5, atomically.

    Layout (format version 2, netCDF-4 conventions, ``xarray.open_datatree(path,
    engine="h5netcdf")``)::

        /            attrs: the errors and run info, steady_file, label, format="slippulse-verify"
        /parameters  attrs: Table-I parameters
        /series      t (s, dimension scale: the measurement times); x_front (m), the errors (1),
                     L (m), v_max (m/s), slip (m), distance (L0), c_p (m/s): (t,);
                     xi_dev (m, dimension scale: ξ − ξ_front), deviation_xi (ξ − ξ_front)/L0;
                     deviation: ln(v/v*+1) − steady, (t, xi_dev)
        /snapshots   t (s, dimension scale), x (m, dimension scale: the SBI grid), v (t, x) m/s,
                     x_front (t,) m: the front on that grid, xi_rel (t, x) m = x − x_front

    (Version 1 stored one group per snapshot, snapshots/000/v ...; the readers of this package
    read only ``series`` and the root attributes, which are laid out as before.)
    """
    from ..core.h5io import atomic_update, coordinate, describe, stamp_format, write_parameters

    def fill(h5):
        for key in list(h5.keys()):
            del h5[key]
        stamp_format(h5, "verify")
        write_parameters(h5, params)
        for k, v in res.errors.items():
            h5.attrs[k] = v
        for k, v in res.info.items():
            h5.attrs[k] = v
        h5.attrs["steady_file"] = source
        h5.attrs["label"] = label
        h5.attrs["steady_converged"] = np.bool_(steady_converged)   # False: --allow-unconverged
        ts = h5.create_group("series")
        t = coordinate(ts, "t", res.t, units="s", long_name="time of the measurement")
        describe(ts.create_dataset("x_front", data=res.x_front), "m",
                 SERIES_LONG_NAMES["x_front"], dims=(t,))
        for k in SERIES:
            describe(ts.create_dataset(k, data=res.series[k]), "1", SERIES_LONG_NAMES[k],
                     dims=(t,))
        for k, unit in EXTRA_SERIES.items():
            if k in res.series:
                describe(ts.create_dataset(k, data=res.series[k]),
                         "L0" if k == "distance" else unit, SERIES_LONG_NAMES[k], dims=(t,))
        if "deviation" in res.series:
            L0 = float(res.info["L"])
            rel = np.asarray(res.series["deviation_xi"], dtype=float)
            xd = coordinate(ts, "xi_dev", rel * L0, units="m", long_name="xi - xi_front")
            dv = describe(ts.create_dataset("deviation", data=res.series["deviation"]), "1",
                          "ln(v/v*+1) - steady", dims=(t, xd))
            dv.attrs["definition"] = "ln(v/v*+1) - steady, rows: samples t, columns: xi_dev"
            describe(ts.create_dataset("deviation_xi", data=rel), "L0",
                     "(xi - xi_front)/L0", dims=(xd,))
        sn = h5.create_group("snapshots")
        if res.snapshots:
            ts_ = np.array([s[0] for s in res.snapshots])
            rel = np.array([s[1] for s in res.snapshots])
            v = np.array([s[2] for s in res.snapshots])
            grid = res.x if res.x is not None else rel[0] - rel[0, 0]
            n = grid.size
            tc = coordinate(sn, "t", ts_, units="s", long_name="time of the snapshot",
                            unlimited=True, chunks=(64,))
            xc = coordinate(sn, "x", grid, units="m", long_name="SBI grid (frame following the "
                            "pulse)")
            for name, data, unit, long in (
                    ("v", v, "m/s", "slip rate"),
                    ("xi_rel", rel, "m", "xi - xi_front = x - x_front at this time")):
                ds = sn.create_dataset(name, data=data, maxshape=(None, n), chunks=(1, n))
                describe(ds, unit, long, dims=(tc, xc))
            describe(sn.create_dataset("x_front", data=grid[0] - rel[:, 0], maxshape=(None,),
                                       chunks=(64,)),
                     "m", "front position on the grid x", dims=(tc,))

    atomic_update(path, fill, replace=True)
