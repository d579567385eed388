"""Instability of steady pulses: perturbed runs, growth rate, unstable mode, fate (docs/stability.md).

A run (:func:`run_perturbation`) seeds a steady pulse (``seeding.seed_pulse``) perturbed by a small
relative amount ε of either sign (``verify.perturb_seed``: the slip-rate excess scaled by
1 + ε, or the driving stress raised by ε τ_d), propagates it with ``verify.verify_pulse`` in
the frame that follows it, and stops at its fate:

* ``grew``: L > grow_L·L⁰, max V > lost_factor·v_max⁰, or the FWHM no longer closes (crack-like);
* ``arrested``: max V < v_max⁰/lost_factor, or the FWHM no longer exists with v_max < v_max⁰;
* ``undecided``: the set distance was reached first.

The deviation from the steady state, d(x) = v_max(x)/v_max⁰ − 1 against the distance x travelled
(in L⁰), grows as e^{s x} in the linear regime; :func:`fit_growth` fits ln|d| by least squares over
the regime chosen by the stated rule of its docstring and returns s with an uncertainty, per pulse
length and per unit time. :func:`mode_shape` extracts the normalised deviation field
y − y⁰ (y = ln(v/v*+1)) in the co-moving frame over that regime.

:func:`run_case` / :func:`read_row` are the runner contract of ``slippulse dynamic scan``
(scan.py): one flat dict of scalars in, one HDF5 file and one summary row out; its
:func:`scan_figures` writes the pair table. The plots live in the plotting layer
(:func:`slippulse.plotting.stability.scan_figures`, table + plots), which the command passes to
``run_scan``.
"""
from __future__ import annotations

import math
import os
import time

import numpy as np

from ..core.atomic import replacing_open
from ..core.params import ParameterError

#: Keys of a scan case (run_case) with their defaults and meaning.
CASE_DEFAULTS = {
    "steady": None,          # steady family file (HDF5 pulse schema), required
    "label": None,           # pulse group, e.g. "td1.0500", required
    "perturbation": "excess",  # "excess" | "tau_d" | "mode" | "mode_front" (the unstable
                               # eigenmode; "mode_front": ε in the frame of the front)
    "mode_file": "",         # "mode": file holding the pulse's spectrum ("": the steady file)
    "eps": 1e-3,             # relative perturbation (signed); 0: unperturbed
    "dx": 4e-3,              # SBI grid spacing, m
    "ahead": 2.0,            # domain ahead of the front, L⁰
    "behind": 3.0,           # domain behind the front, L⁰
    "distance": 4.0,         # largest distance travelled, L⁰
    "samples_per_L": 50,     # measurements per L⁰ travelled
    "beta_cfl": 0.5,         # adaptive time step: CFL factor
    "xi_stab": 0.5,          # adaptive time step: friction-stability factor
    "history": "cheap",      # SOE node set: "cheap" (36 nodes) | "fine" (docs/dynamic.md §2)
    "grow_L": 3.0,           # fate "grew" when L > grow_L·L⁰
    "lost_factor": 10.0,     # fate by max V against v_max⁰ (× or ÷ lost_factor)
    "fit_lo": 1e-3,          # linear regime: |d| from fit_lo ...
    "fit_hi": 3e-2,          # ... to fit_hi (see fit_growth)
    "threads": 1,
    "device": "cpu",         # "cpu" | "cupy" (a GPU, dynamics/device.py) | "numpy" (tests)
    "wall_limit": 0.0,       # s of wall time (seeding included) after which the run stops
                             # where it is and is written, status "stopped: wall limit ..."
                             # (0: none); for machines lent for a fixed time
}
HISTORIES = {"cheap": {"x_min": 1e-6, "x_max": 1e6, "h": 0.8},
             "fine": {"x_min": 1e-8, "x_max": 1e8, "h": 0.5}}
FATES = ("grew", "arrested", "undecided", "failed")


def check_case(case: dict) -> dict:
    """Case merged over :data:`CASE_DEFAULTS`; unknown keys and bad values are ParameterErrors."""
    unknown = sorted(set(case) - set(CASE_DEFAULTS))
    if unknown:
        raise ParameterError(f"unknown case key(s) {unknown}; valid: {sorted(CASE_DEFAULTS)}")
    c = dict(CASE_DEFAULTS)
    c.update(case)
    for key, default in CASE_DEFAULTS.items():      # numbers where numbers belong, named
        if isinstance(default, (int, float)) and not isinstance(default, bool):
            val = c[key]
            if isinstance(val, bool) or not isinstance(val, (int, float)) \
                    or not math.isfinite(val):
                raise ParameterError(f"case key {key}={val!r} must be a finite number")
    if not (isinstance(c["samples_per_L"], int) and 2 <= c["samples_per_L"] <= 10_000):
        raise ParameterError(f"samples_per_L={c['samples_per_L']!r} must be an integer in "
                             "[2, 10000]")
    if not (isinstance(c["threads"], int) and 1 <= c["threads"] <= 1024):
        raise ParameterError(f"threads={c['threads']!r} must be an integer in [1, 1024]")
    for key in ("steady", "label"):
        if not isinstance(c[key], str) or not c[key]:
            raise ParameterError(f"case key {key!r} is required (a string)")
    if c["perturbation"] not in ("excess", "tau_d", "mode", "mode_front"):
        raise ParameterError(f"perturbation={c['perturbation']!r} must be 'excess', 'tau_d', "
                             "'mode' or 'mode_front'")
    if c["perturbation"] in ("mode", "mode_front") and float(c["eps"]) != 0:
        from .eigenmode import check_eps
        check_eps(c["eps"])
    if not isinstance(c["mode_file"], str):
        raise ParameterError("case key 'mode_file' must be a string (a file path, or '')")
    if c["device"] not in ("cpu", "cupy", "numpy"):
        raise ParameterError(f"device={c['device']!r} must be 'cpu', 'cupy' or 'numpy'")
    if c["history"] not in HISTORIES:
        raise ParameterError(f"history={c['history']!r} must be one of {sorted(HISTORIES)}")
    if not abs(float(c["eps"])) < 0.5:
        raise ParameterError(f"eps={c['eps']!r} must satisfy |eps| < 0.5")
    for key in ("dx", "ahead", "distance", "beta_cfl", "xi_stab", "fit_lo"):
        if not 0 < float(c[key]) < math.inf:
            raise ParameterError(f"{key}={c[key]!r} must be finite and > 0")
    if not float(c["behind"]) > 1:
        raise ParameterError(f"behind={c['behind']!r} must be > 1 (pulse lengths)")
    if not float(c["fit_hi"]) > float(c["fit_lo"]):
        raise ParameterError("fit_hi must be > fit_lo")
    if not float(c["grow_L"]) > 1 or not float(c["lost_factor"]) > 1:
        raise ParameterError("grow_L and lost_factor must be > 1")
    if not 0 <= float(c["wall_limit"]) < math.inf:
        raise ParameterError(f"wall_limit={c['wall_limit']!r} must be finite and >= 0 (s; 0: none)")
    return c


def fit_growth(x, d, lo=1e-3, hi=3e-2, min_points=5):
    """Exponential growth rate of a deviation d(x): ln|d| = a + s x over the linear regime.

    Rule: let i₁ be the first sample with |d| ≥ hi (else the last sample); the regime is the
    samples i₀ < i ≤ i₁ after the last sample i₀ < i₁ with |d| < lo, restricted to lo ≤ |d| ≤ hi.
    Below lo the deviation is mixed with the start-up and discretisation level (≈ 1e-4 at the
    production resolution of verify), above hi it saturates (nonlinear). The uncertainty is
    the larger of the least-squares standard error of s and half the difference between the
    slopes fitted on the first and second halves of the regime (curvature = not yet/no longer
    exponential).

    Returns
    -------
    dict
        s, s_err, x0, x1 (the regime), n (samples), sign (of d in the regime); s = NaN when fewer
        than ``min_points`` samples qualify.
    """
    x = np.asarray(x, dtype=float)
    a = np.abs(np.asarray(d, dtype=float))
    out = {"s": math.nan, "s_err": math.nan, "x0": math.nan, "x1": math.nan, "n": 0, "sign": 0}
    ok = np.isfinite(a) & np.isfinite(x)
    if ok.sum() < min_points:
        return out
    above = np.nonzero(ok & (a >= hi))[0]
    i1 = int(above[0]) if above.size else int(np.nonzero(ok)[0][-1])
    below = np.nonzero(ok[:i1] & (a[:i1] < lo))[0]
    i0 = int(below[-1]) if below.size else -1
    idx = np.arange(i0 + 1, i1 + 1)
    idx = idx[ok[idx] & (a[idx] >= lo) & (a[idx] <= hi) & (a[idx] > 0)]   # log |d|: d ≠ 0
    if idx.size < min_points:
        return out
    X, Y = x[idx], np.log(a[idx])
    (s, c0), cov = np.polyfit(X, Y, 1, cov=True)
    se = float(math.sqrt(max(cov[0, 0], 0.0)))
    h = idx.size // 2
    halves = []
    for part in (slice(0, h + 1), slice(h, None)):
        if X[part].size >= 3:
            halves.append(np.polyfit(X[part], Y[part], 1)[0])
    spread = abs(halves[0] - halves[1]) / 2 if len(halves) == 2 else math.nan
    out.update(s=float(s), s_err=float(max(se, spread)) if np.isfinite(spread) else se,
               x0=float(X[0]), x1=float(X[-1]), n=int(idx.size),
               sign=int(np.sign(np.median(np.asarray(d, dtype=float)[idx]))))
    return out


def mode_shape(dev, d, x, fit):
    """Normalised deviation field over the fitted regime, and how much it changes shape.

    Parameters
    ----------
    dev : ndarray (samples, points)
        y − y⁰ in the co-moving frame (``series["deviation"]``).
    d, x : ndarray
        The fitted deviation and the distance (samples).
    fit : dict
        :func:`fit_growth` result.

    Returns
    -------
    mode : ndarray or None
        Mean of the regime's rows, each divided by its value of d (so the mode is the deviation
        field per unit v_max deviation), None if there is no regime.
    spread : float
        max over the regime's rows of ‖row/d − mode‖₂/‖mode‖₂: small when one mode dominates.
    """
    if not np.isfinite(fit["s"]):
        return None, math.nan
    sel = (x >= fit["x0"]) & (x <= fit["x1"]) & np.isfinite(d) & (np.abs(d) > 0)
    return _mode(dev[sel] / d[sel][:, None])


def _mode(rows):
    """Mean of normalised deviation rows and max‖row − mean‖₂/‖mean‖₂ (nan for a zero mean)."""
    mode = rows.mean(axis=0)
    nm = float(np.linalg.norm(mode))
    spread = float(max(np.linalg.norm(r - mode) for r in rows) / nm) if nm > 0 else math.nan
    return mode, spread


def smoothed_c_p(series: dict) -> np.ndarray:
    """c_p(t) of a run (``read_series``) smoothed over 5 samples, the first sample (NaN) set to
    the steady c_p⁰: the front speed ΔX/Δt between samples carries sub-cell position noise."""
    c0 = float(series["attrs"]["c_p"])
    return np.convolve(np.nan_to_num(series["c_p"], nan=c0), np.ones(5) / 5, mode="same")


def _plateau(t, lr, tol, efold):
    """Indices of the final stretch where the local growth rate is constant, and its spread.

    The local rate ℓ_i is the least-squares slope of ln|r| over the samples within ±w/2 of t_i,
    w = efold/|s₀| (s₀: the slope over the second half of the samples, so w spans ``efold``
    e-folds of the response). Going back from the last sample whose window fits, the stretch
    grows while every ℓ in it lies within ±tol of the stretch's median. Returns (indices of the
    samples from the stretch's first window start to the end, half the range of ℓ over the
    stretch), or (None, nan) when the run changes by less than one e-fold (s₀·T < 1) or has too
    few samples.
    """
    n = t.size
    if n < 8:
        return None, math.nan
    h = n // 2
    s0 = np.polyfit(t[h:], lr[h:], 1)[0]
    if not np.isfinite(s0) or abs(s0) * (t[-1] - t[0]) < 1.0 or s0 <= 0:
        return None, math.nan
    w = efold / abs(s0)
    rates, centres = [], []
    for i in range(n):
        if t[i] - w / 2 < t[0] or t[i] + w / 2 > t[-1]:
            continue
        sel = np.abs(t - t[i]) <= w / 2
        if sel.sum() >= 3:
            rates.append(np.polyfit(t[sel], lr[sel], 1)[0])
            centres.append(i)
    if len(rates) < 2:
        return None, math.nan
    rates = np.array(rates)
    j = len(rates) - 1
    while j > 0:
        seg = rates[j - 1:]
        med = np.median(seg)
        if np.all(np.abs(seg - med) <= tol * abs(med)):
            j -= 1
        else:
            break
    seg = rates[j:]
    first = int(np.searchsorted(t, t[centres[j]] - w / 2))
    return np.arange(first, n), float(0.5 * (seg.max() - seg.min()))


#: Observables of a ±ε pair (:func:`pair_growth`): the v_max error, the frame-free potency
#: rate Σ V Δx (``verify.potency_rate``, relative to its mean at t = 0), and the slip potency
#: Σ δ Δx (its time integral as the scheme steps it, in units of the potency of one transit
#: F̄₀ L⁰/c_p⁰; mode-seeded pairs only, :func:`mode_pair_growth`).
PAIR_OBSERVABLES = ("v_max_error", "potency_rate", "slip_potency")


def _observable(series: dict, name: str, ref: float | None = None):
    if name == "v_max_error":
        return series["v_max_error"]
    if name not in PAIR_OBSERVABLES:
        raise ValueError(f"observable={name!r} must be one of {PAIR_OBSERVABLES}")
    if name not in series:
        raise ValueError(f"the run has no {name!r} series (written before it was recorded)")
    if name == "slip_potency":
        return series[name] / ref
    return series[name] / ref - 1.0


def _pair_response(plus: dict, minus: dict, observable: str):
    """(t, r, q, n, v_max error of the −ε run on t) of a ±ε pair: r = (d₊ − d₋)/2 and
    q = (d₊ + d₋)/2 of the observable (:data:`PAIR_OBSERVABLES`) on the +ε run's first n times
    (the −ε run interpolated linearly onto them)."""
    tm = minus["t"]
    n = int(np.searchsorted(plus["t"], tm[-1], side="right"))
    t = plus["t"][:n]
    ref = None
    if observable != "v_max_error" and observable in plus and observable in minus:
        if observable == "slip_potency":
            if "potency_rate" not in plus or "potency_rate" not in minus:
                raise ValueError("the run has no 'potency_rate' series to scale 'slip_potency'")
            a = plus["attrs"]
            ref = (0.5 * (float(plus["potency_rate"][0]) + float(minus["potency_rate"][0]))
                   * float(a["L"]) / float(a["c_p"]))
        else:
            ref = 0.5 * (float(plus[observable][0]) + float(minus[observable][0]))
    obs_p, obs_m = _observable(plus, observable, ref), _observable(minus, observable, ref)
    dm = np.interp(t, tm, obs_m)       # samples differ by < one time step
    vm = np.interp(t, tm, minus["v_max_error"])
    return t, 0.5 * (obs_p[:n] - dm), 0.5 * (obs_p[:n] + dm), n, vm


def _regime_end(plus: dict, vm, d_max: float, *bad) -> int:
    """End of a ±ε pair's linear regime: the first sample where the larger |v_max/v_max⁰ − 1| of
    the two runs (the −ε run's ``vm`` from :func:`_pair_response`) exceeds ``d_max`` or one of the
    masks ``bad`` holds; the number of samples where none does."""
    n = vm.size
    big = np.maximum(np.abs(plus["v_max_error"][:n]), np.abs(vm))
    stop = big > d_max
    for m in bad:
        stop |= m
    i = np.flatnonzero(stop)
    return int(i[0]) if i.size else n


def fit_growth_offset(x, r, min_points: int = 5) -> dict:
    """r = A e^{s x} + B by nonlinear least squares (``scipy.optimize.least_squares``).

    The model of an integrated response: the slip potency of a mode-seeded pair is the time
    integral of its potency rate, so the seed's decaying mismatch leaves a constant B behind
    (∫ e^{−λt} dt), and a constant start offset does too. The start is the log-linear fit of |r|.
    The uncertainty of s is the larger of its standard error (from the Jacobian and the residual
    variance) and half the difference of the slopes fitted on the two halves of the samples.

    Returns
    -------
    dict
        s, s_err, x0, x1, n, A, B (at x = x0), rms (residual rms relative to max |r|); s = NaN
        with fewer than ``min_points`` (≥ 5) finite samples or a fit that fails.
    """
    from scipy.optimize import least_squares

    x = np.asarray(x, dtype=float)
    r = np.asarray(r, dtype=float)
    ok = np.isfinite(x) & np.isfinite(r)
    x, r = x[ok], r[ok]
    out = {"s": math.nan, "s_err": math.nan, "x0": math.nan, "x1": math.nan, "n": int(x.size),
           "A": math.nan, "B": math.nan, "rms": math.nan}
    if x.size < max(min_points, 5):
        return out

    def fit(xs, rs):
        x0, w = xs[0], xs[-1] - xs[0]
        u = (xs - x0) / w                     # scaled: s·w e-folds over the window
        scale = float(np.max(np.abs(rs))) or 1.0
        y = rs / scale
        k0 = np.polyfit(u, np.log(np.maximum(np.abs(y), 1e-300)), 1)[0]

        def res(p):
            return p[0] * np.exp(p[2] * u) + p[1] - y

        def jac(p):
            e = np.exp(p[2] * u)
            return np.column_stack([e, np.ones_like(u), p[0] * u * e])

        e0 = np.exp(k0 * u)
        a0, b0 = np.linalg.lstsq(np.column_stack([e0, np.ones_like(u)]), y, rcond=None)[0]
        sol = least_squares(res, [a0, b0, k0], jac=jac, method="lm", xtol=1e-14, ftol=1e-14)
        if not sol.success or not np.all(np.isfinite(sol.x)):
            return None
        dof = max(u.size - 3, 1)
        var = float(np.sum(sol.fun ** 2)) / dof
        try:
            cov = np.linalg.inv(sol.jac.T @ sol.jac) * var
            se = math.sqrt(max(cov[2, 2], 0.0)) / w
        except np.linalg.LinAlgError:
            se = math.nan
        return (sol.x[2] / w, se, sol.x[0] * scale, sol.x[1] * scale,
                math.sqrt(var) * scale / float(np.max(np.abs(rs))))

    f = fit(x, r)
    if f is None or not math.isfinite(f[1]):
        return out
    s, se, A, B, rms = f
    h = x.size // 2
    halves = [fit(x[p], r[p]) for p in (slice(0, h + 1), slice(h, None)) if x[p].size >= 5]
    halves = [hh for hh in halves if hh is not None]
    spread = abs(halves[0][0] - halves[1][0]) / 2 if len(halves) == 2 else math.nan
    out.update(s=float(s), s_err=float(max(se, spread)) if math.isfinite(spread) else float(se),
               x0=float(x[0]), x1=float(x[-1]), A=float(A), B=float(B), rms=float(rms))
    return out


def pair_growth(plus: dict, minus: dict, eps: float, d_max: float = 0.03, tol: float = 0.05,
                efold: float = 0.5, min_points: int = 5, min_efolds: float = 0.5,
                observable: str = "v_max_error") -> dict:
    """Growth rate from a ±ε pair: the antisymmetric response r = (d₊ − d₋)/2.

    d± = v_max/v_max⁰ − 1 of the runs perturbed by +ε and −ε (``observable="v_max_error"``),
    or F±/F̄₀ − 1 for the frame-free potency rate F = Σ V Δx (``"potency_rate"``; F̄₀ the
    mean of the two runs' F at t = 0), sampled at nearly the same times
    (same distance and sampling: ``verify_pulse`` samples at the first step past each time of
    a fixed grid; the −ε run is interpolated linearly onto the +ε run's times). r cancels the
    unperturbed seed's own drift (start-up and discretisation error, which excites the same
    mode) and the quadratic part of the response; q = (d₊ + d₋)/2 holds both.

    Rule for the linear regime: it ends before the first sample where the larger of the two runs'
    |v_max/v_max⁰ − 1| exceeds d_max, whatever the observable
    (beyond, the cubic response shows: the local rate rises). Before that, the local growth
    rate ℓ (slope of ln|r| over a sliding window of ``efold`` e-folds) approaches a constant
    after the start-up transient of the other modes the perturbation excites (measured at
    1.2 τ_min: ℓ = 34, 26, 23.4, 23.1 per L at 0, 0.05, 0.1, 0.15 L); the regime is the longest
    final stretch over which ℓ stays within ±tol of its median (:func:`_plateau`). s is the
    least-squares slope of ln|r| against t over the regime; its uncertainty the largest of the
    standard error, half the range of ℓ over the regime and half the difference of the slopes of
    the two half-windows. If the response changes by less than one e-fold over the run (decaying
    or neutral), the fit covers the second half of the run instead (``regime = "late half"``).
    s is per second; s·L⁰/c_p⁰ per pulse length. A regime covering less than ``min_efolds``
    e-folds of r gives no rate (``regime = "too short ..."``): the response left the linear
    regime before the transient died (e.g. τ_d changed by 1e−3 at 1.05 τ_min).

    Parameters
    ----------
    plus, minus : dict
        ``read_series`` of the two runs (t, v_max_error, deviation).
    eps : float
        |ε|.

    Returns
    -------
    dict
        s_per_s, s_per_s_err, s_per_L, s_per_L_err, t0, t1, n, sym_ratio (max |q|/|r| in the
        regime), mode (the antisymmetric deviation field per unit r, averaged over the regime, or
        None), mode_xi, mode_spread, r, q, t.
    """
    if observable == "slip_potency":
        raise ValueError("observable='slip_potency' is an integrated response (A e^{st} + B): "
                         "use mode_pair_growth, for mode-seeded pairs")
    tm = minus["t"]
    t, r, q, n, vm = _pair_response(plus, minus, observable)
    a = plus["attrs"]
    conv = float(a["L"]) / float(a["c_p"])
    out = {"s_per_s": math.nan, "s_per_s_err": math.nan, "s_per_L": math.nan,
           "s_per_L_err": math.nan, "t0": math.nan, "t1": math.nan, "n": 0,
           "sym_ratio": math.nan, "mode": None, "mode_spread": math.nan, "r": r, "q": q, "t": t,
           "eps": abs(eps), "regime": "none"}
    ar = np.abs(r)
    i1 = _regime_end(plus, vm, d_max, ~np.isfinite(r))
    if i1 < 2:
        return out
    idx, spread = _plateau(t[:i1], np.log(np.maximum(ar[:i1], 1e-300)), tol, efold)
    out["regime"] = "growth" if idx is not None else "late half"
    if idx is None and i1 < n:
        # saturated (|d±| > d_max) before any plateau of the local rate: no rate
        out["regime"] = "too short (saturated before a plateau)"
        return out
    if idx is None:
        # less than one e-fold over the run: a decaying or neutral response; fit the second
        # half of the run (after the start-up transient)
        idx = np.arange(i1 // 2, i1)
    if idx.size < min_points:
        return out
    f = fit_growth(t[idx], r[idx], lo=0.0, hi=np.inf, min_points=min_points)
    if out["regime"] == "growth" and abs(f["s"]) * (f["x1"] - f["x0"]) < min_efolds:
        # the plateau covers less than min_efolds e-folds of r: the response left the linear
        # regime (d_max) before the start-up transient had died — no rate
        out["regime"] = f"too short ({abs(f['s']) * (f['x1'] - f['x0']):.2f} e-folds)"
        return out
    err = max(f["s_err"], spread) if np.isfinite(spread) else f["s_err"]
    # |q|/|r| where |r| > 0; a sample with r = 0 counts 0 if q = 0 too, else inf (no 0/0 warning)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(ar[idx] > 0, np.abs(q[idx]) / ar[idx],
                         np.where(q[idx] == 0, 0.0, np.inf))
    out.update(s_per_s=f["s"], s_per_s_err=err, s_per_L=f["s"] * conv,
               s_per_L_err=err * conv, t0=f["x0"], t1=f["x1"], n=f["n"],
               sym_ratio=float(np.max(ratio)))
    if "deviation" in plus and "deviation" in minus:
        devm = np.array([np.interp(t, tm, col) for col in minus["deviation"].T]).T
        dev = 0.5 * (plus["deviation"][:n] - devm)
        out["mode"], out["mode_spread"] = _mode(dev[idx] / r[idx][:, None])
        out["mode_xi"] = plus.get("deviation_xi")
    return out


#: Start of the fit of a mode-seeded pair, in pulse lengths travelled: the seed's mismatch
#: relaxes within ≈ 0.05–0.1 L (measured at 1.1 τ_min, docs/stability.md §2).
MODE_FIT_SKIP = 0.1


#: Largest drift of the reference state in a mode-seeded pair: the symmetric part of the potency
#: rate, |(F₊ + F₋)/2F̄₀ − 1|. The antisymmetric response is the linearisation about the pair's
#: mean state; once that has left the steady pulse by |q| (its own discretisation mismatch grows
#: along the same unstable mode), the rate shifts by O(|q|): measured at 1.04 τ_min on 8 mm,
#: +3.7 % at |q| = 2.5 % (docs/stability.md §3).
MODE_DRIFT_MAX = 0.005


def mode_pair_growth(plus: dict, minus: dict, eps: float, observable: str = "potency_rate",
                     skip: float = MODE_FIT_SKIP, d_max: float = 0.03, min_points: int = 5,
                     drift_max: float = MODE_DRIFT_MAX) -> dict:
    """Growth rate of an eigenmode-seeded ±ε pair: least squares of ln|r| over the whole linear
    regime after ``skip`` pulse lengths.

    A mode-seeded pair has no start-up transient to wait for beyond the seed's small mismatch, so
    the plateau rule of :func:`pair_growth` (built for generic seeds) is not needed; fitting the
    whole regime averages the grid-crossing oscillation that the front's passage over the cells
    puts into every observable (period one cell of travel, aliased by the sampling; ±15 % in r at
    1.05 τ_min on an 8 mm grid). r as in :func:`pair_growth`; the regime ends where the larger
    |v_max/v_max⁰ − 1| of the two runs exceeds d_max. Uncertainty: the larger of the standard
    error and half the difference of the slopes over the two halves (:func:`fit_growth`).

    The regime also ends where the pair's mean state has drifted: |(F₊ + F₋)/2F̄₀ − 1| of the
    potency rate F above ``drift_max`` (:data:`MODE_DRIFT_MAX`; runs without F: not applied).

    ``observable="slip_potency"``: r is the antisymmetric slip potency Σ δ Δx, the time integral
    of the potency rate, fitted as A e^{st} + B (:func:`fit_growth_offset`). Integrating divides
    the grid-crossing oscillation (one cell of travel, frequency ω = 2πc_p/Δx) by ω/s relative
    to the growth: ~10⁴ at 1.04 τ_min on 8 mm, where it dominated the potency rate's residual
    (docs/stability.md §3).

    Returns
    -------
    dict
        s_per_s, s_per_s_err, s_per_L, s_per_L_err, t0, t1, n, regime, r, t.
    """
    t, r, _, _, vm = _pair_response(plus, minus, observable)
    a = plus["attrs"]
    conv = float(a["L"]) / float(a["c_p"])
    drift = np.zeros_like(t)
    if "potency_rate" in plus and "potency_rate" in minus:
        drift = np.abs(_pair_response(plus, minus, "potency_rate")[2])
    i1 = _regime_end(plus, vm, d_max, drift > drift_max, ~np.isfinite(r))
    idx = np.nonzero((t[:i1] >= skip * conv) & (r[:i1] != 0))[0]
    out = {"s_per_s": math.nan, "s_per_s_err": math.nan, "s_per_L": math.nan,
           "s_per_L_err": math.nan, "t0": math.nan, "t1": math.nan, "n": int(idx.size),
           "regime": f"too short (fewer than {min_points} samples after {skip:g} L)", "r": r, "t": t}
    if idx.size < min_points:
        return out
    if observable == "slip_potency":
        f = fit_growth_offset(t[idx], r[idx], min_points=min_points)
        how = "A e^{st} + B"
        if not math.isfinite(f["s"]):
            out["regime"] = "no fit (A e^{st} + B did not converge)"
            return out
    else:
        f = fit_growth(t[idx], r[idx], lo=0.0, hi=np.inf, min_points=min_points)
        how = "ln|r|"
    out.update(s_per_s=f["s"], s_per_s_err=f["s_err"], s_per_L=f["s"] * conv,
               s_per_L_err=f["s_err"] * conv, t0=f["x0"], t1=f["x1"], n=f["n"],
               regime=f"mode-seeded: least squares of {how} from {skip:g} L to the end of the "
                      "linear regime")
    return out


def pair_rate_at_zero_drift(plus: dict, minus: dict, start: float, d_max: float = 0.03,
                            observable: str = "slip_potency") -> dict:
    """The rate of a mode-seeded ±ε pair extrapolated to a pair whose mean state has not drifted.

    The ±ε response is the linearisation about the pair's mean state, and that state drifts from
    the steady pulse when the SBI's discrete pulse is not exactly the continuum one (its mismatch
    grows along the unstable mode; docs/stability.md §3), so the rate moves with the
    mean drift q(t) = (F₊ + F₋)/2F̄₀ − 1 of the potency rate. Model, to first order in q: the
    rate is s₀ + k q(t), i.e.

        r(t) = A exp(s₀ (t − t₀) + k Q(t)) + B,   Q(t) = ∫_{t₀}^{t} q dt',

    fitted from ``start`` pulse lengths of travel to where |v_max/v_max⁰ − 1| passes ``d_max``
    (nonlinear least squares for the slip potency; for another observable ln|r| = a + s₀ t + k Q,
    linear, and B = 0). s₀ is the rate at zero drift. It rests on the model (linear in q), so
    quote it beside the fitted rates, not instead of them. Uncertainty: the larger of the
    standard error and half the difference of s₀ fitted on the two halves of the samples.

    Returns
    -------
    dict
        s_per_L, s_per_L_err, slope_per_L (k, per L per unit drift), x0, x1 (L of travel), n,
        q0, q1 (the drift at both ends); s_per_L = NaN with fewer than 8 samples, no spread of
        q, or a fit that fails.
    """
    from scipy.integrate import cumulative_trapezoid
    from scipy.optimize import least_squares

    if "potency_rate" not in plus or "potency_rate" not in minus:
        raise ValueError("the runs have no 'potency_rate' series: the mean drift is unknown")
    t, r, _, _, vm = _pair_response(plus, minus, observable)
    _, _, q, _, _ = _pair_response(plus, minus, "potency_rate")     # on the same times
    a = plus["attrs"]
    conv = float(a["L"]) / float(a["c_p"])
    i1 = _regime_end(plus, vm, d_max, ~np.isfinite(r), ~np.isfinite(q))
    idx = np.nonzero(t[:i1] >= start * conv)[0]
    out = {"s_per_L": math.nan, "s_per_L_err": math.nan, "slope_per_L": math.nan,
           "x0": math.nan, "x1": math.nan, "n": int(idx.size), "q0": math.nan, "q1": math.nan}
    if idx.size < 8:
        return out
    tt, rr, qq = t[idx], r[idx], q[idx]
    out.update(x0=float(tt[0] / conv), x1=float(tt[-1] / conv), q0=float(qq[0]), q1=float(qq[-1]))
    if not np.ptp(qq) > 0:
        return out

    def fit(j):
        tj, rj = tt[j], rr[j]
        Qj = cumulative_trapezoid(qq[j], tj, initial=0.0)
        dt = tj - tj[0]
        if observable != "slip_potency":
            M = np.vstack([np.ones(tj.size), dt, Qj]).T
            y = np.log(np.abs(rj))
            c, *_ = np.linalg.lstsq(M, y, rcond=None)
            res = y - M @ c
            cov = float(res @ res) / max(tj.size - 3, 1) * np.linalg.inv(M.T @ M)
            return c[1], c[2], math.sqrt(max(cov[1, 1], 0.0))
        f0 = fit_growth_offset(tj, rj)
        if not math.isfinite(f0["s"]):
            return math.nan, math.nan, math.nan
        scale = float(np.max(np.abs(rj)))

        def resid(p):
            return (p[2] * np.exp(p[0] * dt + p[1] * Qj) + p[3] - rj) / scale
        sol = least_squares(resid, [f0["s"], 0.0, f0["A"], f0["B"]], method="lm")
        if not sol.success:
            return math.nan, math.nan, math.nan
        J = sol.jac
        dof = max(tj.size - 4, 1)
        try:
            cov = np.linalg.inv(J.T @ J) * float(sol.fun @ sol.fun) / dof
        except np.linalg.LinAlgError:
            return math.nan, math.nan, math.nan
        return sol.x[0], sol.x[1], math.sqrt(max(cov[0, 0], 0.0))

    s0, k, se = fit(np.arange(tt.size))
    if not math.isfinite(s0):
        return out
    h = tt.size // 2
    halves = [fit(np.arange(h)), fit(np.arange(h, tt.size))] if h >= 8 else []
    spread = (0.5 * abs(halves[0][0] - halves[1][0]) if len(halves) == 2
              and all(math.isfinite(x[0]) for x in halves) else 0.0)
    out.update(s_per_L=float(s0 * conv), s_per_L_err=float(max(se, spread) * conv),
               slope_per_L=float(k * conv))
    return out


def _fate(status: str) -> str:
    if status.startswith("failed"):
        return "failed"
    if "grew" in status:
        return "grew"
    if "arrested" in status:
        return "arrested"
    return "undecided"


def run_perturbation(case: dict, progress: bool = False):
    """Run one perturbed pulse to its fate; returns (pulse, params, VerifyResult, analysis dict)."""
    from ..core.h5io import read_pulse, require_converged
    from .verify import VerifySettings, verify_pulse
    from .seeding import DomainSpec
    from ..dynamics.stepper import TimeStepRule

    c = check_case(case)
    pulse, params = read_pulse(c["steady"], c["label"])
    require_converged(c["steady"], [pulse.label])
    spec = DomainSpec(dx=float(c["dx"]), ahead=float(c["ahead"]), behind=float(c["behind"]))
    rule = TimeStepRule(kind="adaptive", beta_cfl=float(c["beta_cfl"]), xi_stab=float(c["xi_stab"]))
    grow_L = float(c["grow_L"])
    wall_limit, wall0 = float(c["wall_limit"]), time.perf_counter()

    def stop(rows):
        if rows[-1][2] > grow_L * pulse.L:
            return f"grew: L > {grow_L:g} L0"
        if wall_limit > 0 and time.perf_counter() - wall0 > wall_limit:
            return f"wall limit {wall_limit:g} s"
        return None

    eps = float(c["eps"])
    eigen = None
    if c["perturbation"] in ("mode", "mode_front"):
        from .eigenmode import leading_mode
        eigen = leading_mode(pulse, params, path=c["steady"], mode_path=c["mode_file"] or None)
    run = VerifySettings(
        rule=rule, n_samples=max(10, int(round(float(c["distance"]) * float(c["samples_per_L"])))),
        n_snapshots=8, history_options=HISTORIES[c["history"]], threads=int(c["threads"]),
        lost_factor=float(c["lost_factor"]),
        perturbation=None if eps == 0 else (c["perturbation"], eps), device=c["device"])
    res = verify_pulse(pulse, params, float(c["distance"]), spec, run, eigen=eigen,
                       progress=progress, stop_check=stop)
    return pulse, params, res, analyse(res, pulse, c)


def analyse(res, pulse, c: dict) -> dict:
    """Fate, growth rates (per L⁰ and per second) and mode-shape spread of a run."""
    se = res.series
    x, t, d = se["distance"], res.t, se["v_max_error"]
    lo, hi = float(c["fit_lo"]), float(c["fit_hi"])
    fx = fit_growth(x, d, lo, hi)
    ft = fit_growth(t, d, lo, hi)
    fl = fit_growth(x, se["L_error"], lo, hi)
    _, spread = mode_shape(se["deviation"], d, x, fx)
    status = res.info["status"]
    return {"fate": _fate(status), "status": status,
            "s_per_L": fx["s"], "s_per_L_err": fx["s_err"], "s_per_s": ft["s"],
            "s_per_s_err": ft["s_err"], "fit_x0": fx["x0"], "fit_x1": fx["x1"],
            "fit_n": fx["n"], "fit_sign": fx["sign"], "s_per_L_from_L": fl["s"],
            "mode_spread": spread,
            "travelled": res.info["travelled"], "t_end": res.info["t_end"],
            "L_end": float(se["L"][-1]), "v_max_end": float(se["v_max"][-1]),
            "n_steps": res.info["n_steps"], "n_points": res.info["n"],
            "wall_time": res.info["wall_time"],
            "tau_d_ratio": pulse.tau_d_ratio, "L0": pulse.L, "c_p0": pulse.c_p,
            "beta0": pulse.beta, "v_max0": res.info["v_max_ref"],
            "eigen_s_per_L": float(res.info.get("eigen_s_per_L", math.nan))}


def run_case(case: dict, out_path: str, progress: bool = False) -> dict:
    """Scan runner: run one perturbed pulse and write ``out_path`` (HDF5) atomically.

    The file holds the verification output (``verify.write_result``: errors, series incl.
    L, c_p, v_max, slip, the deviation field, snapshots) plus the analysis of :func:`analyse` as
    root attributes, ``case_json`` and ``complete = True``. Returns the summary row.
    """
    from ..core.h5io import atomic_update
    from .verify import write_result
    from .scan import case_json

    c = check_case(case)
    wall0 = time.perf_counter()
    pulse, params, res, row = run_perturbation(c, progress=progress)
    row["file"] = os.path.abspath(out_path)
    os.makedirs(os.path.dirname(os.path.abspath(out_path)), exist_ok=True)
    write_result(out_path, res, params, source=os.path.abspath(c["steady"]), label=c["label"])

    def fill(h5):                     # a second commit: until it lands the case is incomplete
        for k, v in row.items():
            h5.attrs[k] = v
        h5.attrs["case_json"] = case_json(case)
        h5.attrs["case_resolved_json"] = case_json(c)
        h5.attrs["run_wall_time"] = time.perf_counter() - wall0
        h5.attrs["complete"] = True
    atomic_update(out_path, fill)
    return row


def read_row(out_path: str) -> dict:
    """The summary row of a finished :func:`run_case` file."""
    from ..core.h5io import format_version, open_h5

    keys = ("fate", "status", "s_per_L", "s_per_L_err", "s_per_s", "s_per_s_err", "fit_x0",
            "fit_x1", "fit_n", "fit_sign", "s_per_L_from_L", "mode_spread", "travelled",
            "t_end", "L_end", "v_max_end", "n_steps", "n_points", "wall_time", "tau_d_ratio",
            "L0", "c_p0", "beta0", "v_max0")
    with open_h5(out_path) as h5:
        format_version(h5, out_path)
        row = {"file": os.path.abspath(out_path)}
        for k in keys:
            v = h5.attrs[k]
            row[k] = v.item() if hasattr(v, "item") else v
        v = h5.attrs.get("eigen_s_per_L", math.nan)       # older files: none
        row["eigen_s_per_L"] = v.item() if hasattr(v, "item") else v
    return row


def read_series(out_path: str) -> dict:
    """Time series of a run file: t, distance, L, c_p, v_max, slip, the errors, the deviation."""
    from ..core.h5io import format_version, open_h5

    with open_h5(out_path) as h5:
        format_version(h5, out_path)
        s = {k: h5["series"][k][...] for k in h5["series"]}
        s["attrs"] = dict(h5.attrs)
    return s


def scan_rows(scan) -> list[dict]:
    """Rows of the finished cases of ``scan`` (:class:`.scan.Scan`): the case keys, then
    :func:`read_row` and the case id, in case order. Unfinished cases are skipped, so a report
    can be drawn while the scan runs."""
    from .scan import case_state
    out = []
    for c in scan.cases:
        path = scan.out_file(c)
        if case_state(path, c) != "done":
            continue
        row = dict(c.params)
        row.update(read_row(path))
        row["id"] = c.id
        out.append(row)
    return out


def pair_variant(p: dict, base: dict) -> str:
    """Which settings of a pair (a :func:`pair_table` row) differ from the scan's base pair:
    ε, the grid (Δx, ξ_s), the domain, the history, the perturbation; "base" when none."""
    diffs = []
    if abs(p["eps"] - base["eps"]) > 1e-12:
        diffs.append(f"ε = {p['eps']:g}")
    if abs(float(p["dx"]) - float(base["dx"])) > 1e-12 or \
            abs(float(p["xi_stab"]) - float(base["xi_stab"])) > 1e-12:
        diffs.append(f"Δx = {float(p['dx']) * 1e3:g} mm, ξ_s = {float(p['xi_stab']):g}")
    if float(p["ahead"]) != float(base["ahead"]) or float(p["behind"]) != float(base["behind"]):
        diffs.append(f"domain {float(p['behind']):g}+{float(p['ahead']):g} L")
    if p["history"] != base["history"]:
        diffs.append(f"history {p['history']}")
    if p.get("perturbation") != base.get("perturbation"):
        diffs.append(f"perturbation {p['perturbation']}")
    return "; ".join(diffs) or "base"


#: Case keys that do not distinguish the two members of a ±ε pair.
_PAIR_IGNORE = ("eps", "id", "status", "file")


def pair_rows(rows: list[dict]) -> list[tuple[dict, dict]]:
    """Group scan rows into ±ε pairs: same case keys (``CASE_DEFAULTS``) except the sign of ε."""
    def key(r):
        return tuple((k, r.get(k)) for k in sorted(CASE_DEFAULTS) if k not in _PAIR_IGNORE) + \
            (("abs_eps", abs(float(r.get("eps", 0.0)))),)
    groups: dict = {}
    for r in rows:
        if not r.get("file") or float(r.get("eps", 0.0)) == 0.0:
            continue
        groups.setdefault(key(r), {})[1 if float(r["eps"]) > 0 else -1] = r
    return [(g[1], g[-1]) for g in groups.values() if 1 in g and -1 in g]


#: Columns of the pair table (growth_pairs.csv).
PAIR_COLUMNS = ("label", "tau_d_ratio", "eps", "dx", "xi_stab", "ahead", "behind", "history",
                "perturbation", "s_per_L", "s_per_L_err", "s_per_s", "s_per_s_err", "t0", "t1",
                "n", "regime", "sym_ratio", "mode_spread", "fate_plus", "fate_minus",
                "wall_time", "eigen_s_per_L", "rel_to_eigen",
                "s_per_L_potency_rate", "s_per_L_err_potency_rate", "rel_to_eigen_potency_rate",
                "s_per_L_slip_potency", "s_per_L_err_slip_potency", "rel_to_eigen_slip_potency",
                "s_per_L_zero_drift", "s_per_L_err_zero_drift", "rel_to_eigen_zero_drift")

#: Where the pair table's zero-drift fit (:func:`pair_rate_at_zero_drift`) starts, L of travel:
#: after the seed's start-up transient at 1.04–1.05 τ_min (≈ 2 L); where it lasts longer (≈ 4–5
#: L at 1.03 τ_min) the fit's two halves disagree and its error bar says so.
ZERO_DRIFT_START = 2.0


def pair_table(rows: list[dict]) -> list[dict]:
    """One row per ±ε pair: the case keys, :func:`pair_growth` and the fates of both signs."""
    out = []
    for rp, rm in pair_rows(rows):
        sp, sm = read_series(rp["file"]), read_series(rm["file"])
        g = pair_growth(sp, sm, float(rp["eps"]))
        c = check_case({k: rp[k] for k in CASE_DEFAULTS if k in rp})
        row = {k: c[k] for k in ("label", "dx", "xi_stab", "ahead", "behind", "history",
                                 "perturbation")}
        for k in ("dx", "xi_stab", "ahead", "behind"):
            row[k] = float(row[k])
        row["tau_d_ratio"] = float(rp.get("tau_d_ratio"))
        row["eps"] = abs(float(rp["eps"]))
        row.update({k: g[k] for k in ("s_per_L", "s_per_L_err", "s_per_s", "s_per_s_err", "t0",
                                      "t1", "n", "regime", "sym_ratio", "mode_spread")})
        row["fate_plus"], row["fate_minus"] = rp.get("fate"), rm.get("fate")
        se = float(rp.get("eigen_s_per_L", math.nan))
        row["eigen_s_per_L"] = se
        row["rel_to_eigen"] = g["s_per_L"] / se - 1.0 if math.isfinite(se) and se else math.nan
        for obs in PAIR_OBSERVABLES[1:]:
            # the frame-free potency rate (runs written before it have none: nan); mode-seeded
            # pairs by the whole-regime fit (mode_pair_growth), the others by the plateau rule
            # the slip potency (an integrated response) by the mode-seeded fit only
            mode_seeded = c["perturbation"] in ("mode", "mode_front")
            fit = mode_pair_growth if mode_seeded else pair_growth
            have = obs in sp and obs in sm and (mode_seeded or obs != "slip_potency")
            gi = (fit(sp, sm, float(rp["eps"]), observable=obs)
                  if have else {"s_per_L": math.nan, "s_per_L_err": math.nan})
            row[f"s_per_L_{obs}"], row[f"s_per_L_err_{obs}"] = gi["s_per_L"], gi["s_per_L_err"]
            row[f"rel_to_eigen_{obs}"] = (gi["s_per_L"] / se - 1.0 if math.isfinite(se) and se
                                          else math.nan)
        z = {"s_per_L": math.nan, "s_per_L_err": math.nan}
        if mode_seeded and all(k in x for k in ("slip_potency", "potency_rate") for x in (sp, sm)):
            z = pair_rate_at_zero_drift(sp, sm, start=ZERO_DRIFT_START)
        row["s_per_L_zero_drift"], row["s_per_L_err_zero_drift"] = z["s_per_L"], z["s_per_L_err"]
        row["rel_to_eigen_zero_drift"] = (z["s_per_L"] / se - 1.0 if math.isfinite(se) and se
                                          else math.nan)
        row["wall_time"] = float(rp.get("wall_time", math.nan)) + float(rm.get("wall_time", math.nan))
        row["_growth"] = g
        row["_file_plus"], row["_file_minus"] = rp["file"], rm["file"]
        out.append(row)
    return out


def write_pair_table(rows: list[dict], out_dir: str) -> list[str]:
    """The pair table of a scan's rows (:func:`pair_table`) as ``out_dir/growth_pairs.csv``
    (written atomically); the list of the paths written (empty when there is no ±ε pair)."""
    import csv

    os.makedirs(out_dir, exist_ok=True)
    pairs = pair_table(rows)
    if not pairs:
        return []
    path = os.path.join(out_dir, "growth_pairs.csv")
    with replacing_open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(PAIR_COLUMNS), extrasaction="ignore")
        w.writeheader()
        for r in pairs:
            w.writerow(r)
    return [path]


def scan_figures(rows: list[dict], out_dir: str) -> list[str]:
    """Scan hook of the runner contract, without plots: the pair table only
    (:func:`write_pair_table`). ``slippulse dynamic scan`` passes
    :func:`slippulse.plotting.stability.scan_figures` instead, which adds the figures."""
    return write_pair_table(rows, out_dir)


def steady_curve(*paths) -> np.ndarray:
    """(L, c_p, τ_d/τ_min, β) of every pulse in the steady family files (one per τ_d), sorted by
    L (m, m/s)."""
    from ..core.h5io import list_pulses, read_pulse
    pts = {}
    for path in paths:
        for lab in list_pulses(path):
            pu = read_pulse(path, lab)[0]
            pts[round(pu.tau_d_ratio, 6)] = (pu.L, pu.c_p, pu.tau_d_ratio, pu.beta)
    return np.array(sorted(pts.values()))


def line_deviation(L, c_p, curve: np.ndarray) -> np.ndarray:
    """Relative distance of (L, c_p) points from the steady line: c_p/c_p⁰(L) − 1.

    c_p⁰(L) interpolates the steady family (``steady_curve``) linearly in ln L – ln c_p on its
    monotone branch containing most points (the steady L(τ_d) has a minimum near 1.29 τ_min, so
    the line turns back there; only the branch L ≥ L_min is used). NaN outside the branch's L range.
    """
    L = np.asarray(L, dtype=float)
    c = np.asarray(c_p, dtype=float)
    imin = int(np.argmin(curve[:, 0]))
    br = curve[np.argsort(curve[:, 2])]            # by τ_d ascending: L descending to the minimum
    br = br[br[:, 2] <= curve[imin, 2] + 1e-12]
    br = br[np.argsort(br[:, 0])]
    with np.errstate(invalid="ignore", divide="ignore"):
        lnc = np.interp(np.log(L), np.log(br[:, 0]), np.log(br[:, 1]), left=np.nan,
                        right=np.nan)
        return c / np.exp(lnc) - 1.0
