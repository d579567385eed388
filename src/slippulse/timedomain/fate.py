"""The fate of an eigenmode-seeded pulse under a uniform load: run until it is decided
(docs/motion.md §3).

A run is the verification run of ``verify.verify_pulse`` (frame following the pulse, the pulse
seeded with ε × its unstable mode and the mode's growing past) that stops at its fate
(:class:`FateRule`), not at a distance. The load at infinity is τ_d. On the periodic domain the
pulse has images; ``far_field="steady"`` (default) removes those of the steady pulse (a static
field in the frame of the front), which leaves the images of the deviation only: at 1.2 τ_min the
fate times on 5 L and 10 L domains agree to 0.3 %, where with the images left in
(``far_field="none"``) L differs by 6 % within half the run and both signs of ε arrest.
"""
from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass

import numpy as np

#: Fates, in the order they are checked at each sample ("grew xG" names the rule's growth G).
FATES = ("arrested", "grew x3", "near c_s", "crack-like", "outgrew the domain", "undecided")
_GREW = re.compile(r"grew x[0-9.e+-]+$")


@dataclass(frozen=True)
class FateRule:
    """When a run's fate is decided, checked at every sample (L, v_max from the FWHM of
    ln(v/v*+1) and its parabolic peak; c_p from the front's travel over the last ``smooth``
    samples):

    * ``arrested``: v_max < v_max⁰/arrest (the slip rate falls toward creep);
    * ``grew xG``: L > growth·L⁰ (G = growth);
    * ``near c_s``: c_p > (1 − near_cs)·c_s;
    * ``crack-like``: the rear half-maximum edge runs backward in the lab, c_p − dL/dt <
      −backward·c_s over the last ``smooth`` samples with v_max > v_max⁰ (the slipping region
      expands at both ends: nothing heals; backward = 0 turns this off), or the FWHM no longer
      closes behind the peak with v_max > v_max⁰ (the slip rate behind the front stays above
      half the peak's ln), or max V > lost·v_max⁰ (the verify run's own stop; set far above
      the others);
    * ``outgrew the domain``: the slip rate nowhere on the ring falls below half the peak's ln
      (the pulse, or rupture, is longer than the domain: a bigger domain decides);
    * ``undecided``: the distance limit came first.
    """

    arrest: float = 10.0
    growth: float = 3.0
    near_cs: float = 0.01
    smooth: int = 5
    lost: float = 1e3
    backward: float = 0.1

    def check(self, rows, L0: float, v_max0: float, c_s: float) -> str | None:
        """The fate decided by the measured rows (t, X, L, v_max, ...), or None."""
        t, X, L, vmax = (np.asarray([r[i] for r in rows], float) for i in range(4))
        if vmax[-1] < v_max0 / self.arrest:
            return "arrested"
        if L[-1] > self.growth * L0:
            return f"grew x{self.growth:g}"
        k = min(self.smooth, t.size - 1)
        if k >= 1 and (X[-1] - X[-1 - k]) / (t[-1] - t[-1 - k]) > (1 - self.near_cs) * c_s:
            return "near c_s"
        rear = X - L                               # the rear half-maximum edge, lab frame
        if (self.backward > 0 and k >= 1 and vmax[-1] > v_max0
                and (rear[-1] - rear[-1 - k]) / (t[-1] - t[-1 - k]) < -self.backward * c_s):
            return "crack-like"
        return None


@dataclass
class FateResult:
    """The verify run (trajectory in ``run.series``), its fate and the time and distance to it."""

    run: object                   # verify.VerifyResult
    fate: str
    t_fate: float                 # s (nan: undecided)
    distance_fate: float          # L⁰ travelled (nan: undecided)
    rule: FateRule


def fate_of(status: str) -> str:
    """The fate named by a verify run's status: a FateRule stop, the run's own stops (crack-like
    for a pulse that grew past measure, arrested for one that faded), or undecided."""
    m = re.match(r"stopped: (.*)$", status)
    if m and (m.group(1) in FATES or _GREW.match(m.group(1))):
        return m.group(1)
    if status.startswith("pulse lost: grew"):
        # the FWHM found no fall below half the maximum anywhere on the ring: the pulse is longer
        # than the domain can show, which says nothing about its shape
        return "outgrew the domain" if "domain too short" in status else "crack-like"
    if status.startswith("pulse lost: arrested"):
        return "arrested"
    if status == "finished":
        return "undecided"
    return f"failed ({status})"


def run_fate(pulse, params, eigen, eps: float, spec, distance: float,
             rule: FateRule = FateRule(), samples_per_L: int = 200, progress: bool = True,
             device: str = "cpu", far_field: str = "steady", frame: str = "front") -> FateResult:
    """Seed ``pulse`` + ε × ``eigen`` (its unstable mode) under the uniform τ_d and run until its
    fate or ``distance`` pulse lengths (``verify.verify_pulse``, adaptive Δt, SOE history).
    ``far_field``: "steady", the images of the steady pulse removed (and its tail beyond the
    window added), a static field in the frame of the front (``seeding.seed_pulse``); "none", the
    periodic train of the pulse and its images under τ_d. ``frame``: "front" (default), ε is
    the mode's largest change of ln(v/v*+1) in the frame of the front, the front's displacement
    carried exactly (``perturbation="mode_front"``); "lab", at fixed ξ (``"mode"``), where the
    mode's front displacement takes ε, leaving the pulse body ε × 5e-3 at 1.1 τ_min
    (docs/stability.md §2): too little over the seed's own error there."""
    if frame not in ("front", "lab"):
        raise ValueError(f"frame={frame!r} must be 'front' or 'lab'")
    from .verify import VerifySettings, verify_pulse
    from ..dynamics.stepper import TimeStepRule

    def stop(rows):
        return rule.check(rows, pulse.L, pulse.v_max, params.c_s)

    n = max(2, int(math.ceil(samples_per_L * distance)))
    settings = VerifySettings(rule=TimeStepRule(kind="adaptive"), far_field=far_field,
                              n_samples=n, lost_factor=rule.lost, device=device,
                              perturbation=("mode_front" if frame == "front" else "mode",
                                            float(eps)))
    res = verify_pulse(pulse, params, distance, spec, settings, eigen=eigen, stop_check=stop,
                       progress=progress)
    fate = fate_of(res.info["status"])
    decided = fate not in ("undecided",) and not fate.startswith("failed")
    t_f = float(res.info["t_end"]) if decided else float("nan")
    d_f = float(res.info["travelled"]) if decided else float("nan")
    return FateResult(res, fate, t_f, d_f, rule)


def write_fate(path: str, fr: FateResult, params, source: str = "", label: str = "") -> None:
    """The verify file layout (``verify.write_result``) with the fate, its time and distance and
    the rule as root attributes."""
    from ..core.h5io import atomic_update
    from .verify import write_result
    write_result(path, fr.run, params, source=source, label=label)

    def fill(h5):
        h5.attrs["fate"] = fr.fate
        h5.attrs["t_fate"] = fr.t_fate
        h5.attrs["t_fate_units"] = "s"
        h5.attrs["distance_fate"] = fr.distance_fate
        h5.attrs["distance_fate_units"] = "L0"
        for k, v in asdict(fr.rule).items():
            h5.attrs[f"fate_rule_{k}"] = v
    atomic_update(path, fill)


def summary(fr: FateResult) -> str:
    """One line: the fate, when, and where L and c_p went."""
    s = fr.run.series
    inf = fr.run.info
    L, cp = np.asarray(s["L"]), np.asarray(s["c_p"])
    when = (f" after {fr.distance_fate:.3g} L0 ({fr.t_fate:.4g} s)"
            if math.isfinite(fr.t_fate) else f" within {inf['travelled']:.3g} L0")
    return (f"fate of td{inf['tau_d_ratio']:.4f} eps={inf['eps']:+.3g} ({inf['n']} points, "
            f"{inf['ahead']:g}+{inf['behind']:g} L, far field {inf['far_field']}): {fr.fate}{when}; "
            f"L {L[0]:.4g} -> {L[-1]:.4g} m, c_p {np.nanmin(cp[1:2]) if cp.size > 1 else np.nan:.4g}"
            f" -> {cp[-1]:.4g} m/s; {inf['n_steps']} steps, wall={inf['wall_time']:.0f} s")


def read_fate(path: str) -> dict:
    """A fate (or verify) file's trajectory and description: arrays t (s), x_front (m), L (m),
    v_max (m/s), the slip-rate ``snapshots`` (dict t, xi_rel, v) where stored, and the root
    attributes (tau_d_ratio, eps, fate, distance_fate, ahead, behind,
    n, ...; the steady pulse's L as L0)."""
    from ..core.h5io import open_h5
    with open_h5(path, "fate file") as h5:
        s = h5["series"]
        out = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in h5.attrs.items()}
        out["L0"] = out.get("L")                   # the steady pulse's; the series below
        out.update({k: np.asarray(s[k][...], float) for k in ("t", "x_front", "L", "v_max")})
        if "snapshots" in h5 and "xi_rel" in h5["snapshots"]:
            g = h5["snapshots"]
            out["snapshots"] = {k: np.asarray(g[k][...], float) for k in ("t", "xi_rel", "v")}
    if "status" in out:                     # the fate as this version names it
        out["fate"] = fate_of(str(out["status"]))
    out["path"] = path
    return out


def domain_difference(a: dict, b: dict, upto: float = 1.0) -> dict:
    """Two runs of one pulse and ε on different domains (:func:`read_fate` dicts): the largest
    |L_b/L_a − 1| and |c_p,b/c_p,a − 1| over the times both ran, up to the fraction ``upto`` of
    the earlier end (L_b, c_p,b interpolated linearly in t onto a's samples), and the relative
    difference of their fate times."""
    from .motion import smoothed_speed
    t_end = upto * min(a["t"][-1], b["t"][-1])
    k = a["t"] <= t_end
    Lb = np.interp(a["t"][k], b["t"], b["L"])
    ca, cb = smoothed_speed(a["t"], a["x_front"]), smoothed_speed(b["t"], b["x_front"])
    cbi = np.interp(a["t"][k], b["t"], cb)
    with np.errstate(invalid="ignore"):
        dL = np.nanmax(np.abs(Lb / a["L"][k] - 1.0))
        dc = np.nanmax(np.abs(cbi / ca[k] - 1.0))
    ta, tb = float(a.get("t_fate", np.nan)), float(b.get("t_fate", np.nan))
    return {"dL": float(dL), "dc": float(dc), "t_end": float(t_end),
            "dt_fate": (tb / ta - 1.0) if np.isfinite(ta) and np.isfinite(tb) else float("nan")}


def time_law(eps, t_fate):
    """t_fate = a + b ln|ε| by least squares (≥ 3 runs): (a, b, b's standard error). A linear
    instability of rate s followed by an ε-independent nonlinear stage gives b = −1/s."""
    x, y = np.log(np.abs(np.asarray(eps, float))), np.asarray(t_fate, float)
    if x.size < 3:
        raise ValueError(f"a time law needs at least 3 runs; got {x.size}")
    A = np.column_stack([np.ones_like(x), x])
    coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ coef
    cov = np.linalg.inv(A.T @ A) * (r @ r) / max(x.size - 2, 1)
    return float(coef[0]), float(coef[1]), float(np.sqrt(cov[1, 1]))


def departure_time(t, L, L_ref: float, start: float = 0.01) -> float:
    """The first time |L/L_ref − 1| ≥ ``start`` (linear in t between samples; nan: never). With
    the time law it splits the time to a fate into the linear stage (to the departure, ∝ −ln|ε|/s)
    and the rest (the nonlinear stage and the fate rule's threshold, ε-independent if the
    picture holds)."""
    t, d = np.asarray(t, float), np.abs(np.asarray(L, float) / L_ref - 1.0)
    k = np.flatnonzero(d >= start)
    if not k.size:
        return float("nan")
    i = int(k[0])
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (start - d[i - 1]) / (d[i] - d[i - 1]) * (t[i] - t[i - 1]))


def time_law_offset(eps, t, s: float | None = None):
    """t = a − ln|ε + ε₀|/s' fitted to runs of either sign of ε (the time to a departure from
    the steady L is the same linear stage for both): ε₀ is the seed's own projection on the mode
    in units of ε (the grid's and the period's error of the seeded pulse), which adds to every
    ε, so that a plain fit of t = a + b ln|ε| finds |b s| ≠ 1 when ε₀ is not ≪ the smallest
    |ε|, and an ε below |ε₀| of the opposite sign meets the other fate. With ``s`` given, s' = s
    (≥ 3 runs); without, s' is fitted too (≥ 4 runs). Returns a dict: a, eps0, eps0_err, rate
    (s'), rate_err (0 when fixed), rms (s); errors from the residuals (nan with no degree of
    freedom left)."""
    from scipy.optimize import least_squares
    e, y = np.asarray(eps, float), np.asarray(t, float)
    free = s is None
    need = 4 if free else 3
    if e.size < need:
        raise ValueError(f"the offset law needs at least {need} runs; got {e.size}")
    s0 = float(s) if not free else float(np.log(np.abs(e).max() / np.abs(e).min())
                                         / max(np.ptp(y), 1e-300))

    def res(p):
        rate = p[2] if free else s0
        return p[0] - np.log(np.maximum(np.abs(e + p[1]), 1e-300)) / rate - y

    # |ε + ε₀| is singular where ε₀ = −ε: start on each side of every run's |ε| (and at 0) and
    # keep the best fit
    m = np.sort(np.abs(e))
    cuts = np.r_[0.0, 0.5 * m[0], np.sqrt(m[1:] * m[:-1]), 2.0 * m[-1]]
    fit = None
    for c in np.r_[cuts, -cuts[1:]]:
        p0 = [float(np.mean(y + np.log(np.abs(e + c) + 1e-300) / s0)), float(c)] + \
             ([s0] if free else [])
        f = least_squares(res, p0, x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15)
        if fit is None or f.cost < fit.cost:
            fit = f
    r, J = fit.fun, fit.jac
    dof = e.size - fit.x.size
    try:
        cov = np.linalg.inv(J.T @ J) * ((r @ r) / dof if dof > 0 else np.nan)
        errs = np.sqrt(np.diag(cov))
    except np.linalg.LinAlgError:
        errs = np.full(fit.x.size, np.nan)
    return {"a": float(fit.x[0]), "eps0": float(fit.x[1]), "eps0_err": float(errs[1]),
            "rate": float(fit.x[2]) if free else s0,
            "rate_err": float(errs[2]) if free else 0.0,
            "rms": float(np.sqrt(np.mean(r ** 2)))}
