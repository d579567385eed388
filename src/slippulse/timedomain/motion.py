"""The one-degree-of-freedom equation of motion of a pulse along its steady line (docs/motion.md).

A pulse of length L under a uniform load τ_d changes its length at the rate

    dL/dt = s(L) · (τ⁰(L) − τ_d) / τ⁰′(L),        c_p(t) = c_p⁰(L(t)),

where τ⁰(L), c_p⁰(L) are the steady line of a family and s(L) > 0 the growth rate of its unstable
eigenvalue. It is the rate dL/dt = F(L, τ_d) taken to first order in τ_d − τ⁰(L) at fixed L, with
∂_τF fixed by the two facts F(L, τ⁰(L)) = 0 and ∂_L F = s on the line (so ∂_τF = −s/τ⁰′): no fitted
constant. The family enters only through interpolants in ln L; the uncertainty band of a trajectory
is the envelope of the trajectories with s ± s_err and with two interpolation rules (cubic spline
and PCHIP), so it carries both the error of the rates and that of the interpolation.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import UsageError

#: Interpolation rules of the steady line, in ln L: the first is the trajectory of record, the
#: others enter its uncertainty band.
RULES = ("spline", "pchip")


class MotionInputError(UsageError):
    """Bad input to the equation of motion (a family without rates, τ_d or L outside it)."""


@dataclass(frozen=True)
class SteadyLine:
    """A family as functions of the pulse length: τ⁰/τ_min, c_p⁰ at every pulse (sorted by L) and
    s ± s_err (1/s) at the pulses whose spectrum is stored. L must be monotone along the family in
    τ_d (true below 1.2 τ_min; above 1.29 L turns and the line is not a function of L)."""

    L: np.ndarray                 # m, every pulse, increasing
    tau_ratio: np.ndarray         # τ⁰/τ_min at L
    c_p: np.ndarray               # m/s at L
    L_rated: np.ndarray           # m, increasing
    s: np.ndarray                 # 1/s at L_rated
    s_err: np.ndarray             # 1/s at L_rated
    tau_min: float = float("nan")  # Pa
    c_s: float = float("nan")      # m/s
    source: str = ""

    @classmethod
    def from_arrays(cls, L, tau_ratio, c_p, L_rated, s, s_err, **kw) -> "SteadyLine":
        """Sort by L and check: at least 3 pulses and 3 rated pulses, L strictly monotone in τ⁰,
        s > 0 (a growth rate) and s_err ≥ 0; MotionInputError otherwise."""
        L, tau, c = (np.asarray(a, float) for a in (L, tau_ratio, c_p))
        Ls, s, se = (np.asarray(a, float) for a in (L_rated, s, s_err))
        k, ks = np.argsort(L), np.argsort(Ls)
        L, tau, c, Ls, s, se = L[k], tau[k], c[k], Ls[ks], s[ks], se[ks]
        if L.size < 3:
            raise MotionInputError(f"the family has {L.size} converged pulses; the equation of "
                                   "motion needs at least 3")
        if Ls.size < 3:
            raise MotionInputError(f"the family has {Ls.size} pulses with a stored growth rate "
                                   "(spectrum s); the equation of motion needs at least 3 "
                                   "(`slippulse steady stability FILE`)")
        if np.any(np.diff(L) <= 0) or not (np.all(np.diff(tau) < 0) or np.all(np.diff(tau) > 0)):
            raise MotionInputError("L is not monotone along the family in tau_d: the steady "
                                   "line is not a function of L (use pulses below 1.29 tau_min)")
        if np.any(s <= 0) or np.any(se < 0) or not np.all(np.isfinite(np.r_[s, se])):
            raise MotionInputError("the stored growth rates must be positive with s_err >= 0")
        return cls(L, tau, c, Ls, s, se, **kw)

    @classmethod
    def from_family(cls, paths) -> "SteadyLine":
        """The converged pulses and the stored rates of record (spectrum attributes ``s``,
        ``s_err``) of one or several family files taken together (e.g. the branch above 1.2 and
        the family below it; a label in several files: the first file's)."""
        from ..core.h5io import open_h5, read_parameters
        from ..spectrum.law import family_curve, family_rates
        paths = [str(paths)] if isinstance(paths, (str, bytes)) or hasattr(paths, "__fspath__") \
            else [str(p) for p in paths]
        tau_min = float("nan")
        for i, path in enumerate(paths):
            with open_h5(path, "FILE") as h5:
                params = read_parameters(h5)
                if i == 0:
                    first = params
                    tau_min = next((float(g.attrs["tau_min"]) for g in
                                    h5.get("pulses", {}).values() if "tau_min" in g.attrs),
                                   float("nan"))
                elif params != first:
                    raise MotionInputError(f"{path}: its parameters differ from {paths[0]}'s")
        curve = family_curve(paths)
        rates = family_rates(paths)
        return cls.from_arrays(curve["L"], curve["tau_d_ratio"], curve["beta"] * first.c_s,
                               rates["L"], rates["s"], rates["s_err"], tau_min=tau_min,
                               c_s=first.c_s, source=", ".join(paths))

    @property
    def L_range(self) -> tuple[float, float]:
        """Where the equation is defined: the pulses' L range within the rated pulses' range."""
        return (max(self.L[0], self.L_rated[0]), min(self.L[-1], self.L_rated[-1]))

    @property
    def tau_range(self) -> tuple[float, float]:
        """τ⁰/τ_min over L_range."""
        a, b = (float(np.interp(np.log(x), np.log(self.L), self.tau_ratio))
                for x in self.L_range)
        return (min(a, b), max(a, b))

    def functions(self, rule: str = "spline"):
        """(τ⁰, τ⁰′, c_p⁰, s) as functions of L (vectorised) under one interpolation rule, all in
        ln L (ln s for the rate, which stays positive)."""
        from scipy.interpolate import CubicSpline, PchipInterpolator
        if rule not in RULES:
            raise ValueError(f"rule={rule!r} must be one of {RULES}")
        make = CubicSpline if rule == "spline" else PchipInterpolator
        x, xs = np.log(self.L), np.log(self.L_rated)
        tau, cp, ls = make(x, self.tau_ratio), make(x, self.c_p), make(xs, np.log(self.s))
        dtau = tau.derivative()
        return (lambda L: tau(np.log(L)), lambda L: dtau(np.log(L)) / L,
                lambda L: cp(np.log(L)), lambda L: np.exp(ls(np.log(L))))

    def s_err_at(self, L):
        """s_err/s interpolated linearly in ln L (the relative error of the rates)."""
        return np.interp(np.log(L), np.log(self.L_rated), self.s_err / self.s)

    def equilibrium(self, tau_d_ratio: float, rule: str = "spline") -> float:
        """The steady pulse's L at τ_d (τ⁰(L) = τ_d), by root finding on the interpolant."""
        from scipy.optimize import brentq
        tau, *_ = self.functions(rule)
        lo, hi = self.L_range
        return float(brentq(lambda L: tau(L) - tau_d_ratio, lo, hi, xtol=1e-14 * hi))


@dataclass
class Trajectory:
    """L(t), c_p(t) of the model with their band; ``fate`` says how the integration ended."""

    t: np.ndarray                 # s
    L: np.ndarray                 # m
    L_lo: np.ndarray
    L_hi: np.ndarray
    c_p: np.ndarray               # m/s
    c_p_lo: np.ndarray
    c_p_hi: np.ndarray
    x: np.ndarray                 # m, distance travelled
    fate: str
    t_fate: float                 # s (nan: none within the duration)
    info: dict = field(default_factory=dict)


def rate(line_fns, tau_d_ratio: float, s_scale: float = 1.0):
    """dL/dt(L) of the model under one set of interpolants: s (τ⁰ − τ_d)/τ⁰′."""
    tau, dtau, _, s = line_fns

    def f(L):
        return s_scale * s(L) * (tau(L) - tau_d_ratio) / dtau(L)
    return f


def integrate(line: SteadyLine, tau_d_ratio: float, L0: float, duration: float,
              n_out: int = 400, rtol: float = 1e-10) -> Trajectory:
    """Integrate the equation of motion from L(0) = L0 under τ_d over ``duration`` seconds.

    The trajectory of record uses the cubic spline and s; the band is the envelope over the rules
    of :data:`RULES` and s·(1 ± s_err/s) (each variant integrated on its own; at each output time
    over the variants still inside the family). Integration stops when L leaves the family's
    range (fate "left the family (short end)" or "(long end)"), or at ``duration`` ("within the
    family"). MotionInputError for τ_d outside the family's τ range, L0 outside its L range, or a
    duration that is not positive."""
    from scipy.integrate import solve_ivp
    wall0, cpu0 = time.perf_counter(), time.process_time()
    lo, hi = line.L_range
    tlo, thi = line.tau_range
    if not (np.isfinite(tau_d_ratio) and tlo <= tau_d_ratio <= thi):
        raise MotionInputError(f"tau-d={tau_d_ratio!r} is outside the family: valid "
                               f"[{tlo:.6g}, {thi:.6g}] tau_min (its pulses with a growth rate)")
    if not (np.isfinite(L0) and lo <= L0 <= hi):
        raise MotionInputError(f"length={L0!r} is outside the family: valid [{lo:.6g}, {hi:.6g}] m")
    if not (np.isfinite(duration) and duration > 0):
        raise MotionInputError(f"duration={duration!r} must be a finite number > 0 (s)")
    t_out = np.linspace(0.0, duration, n_out + 1)
    out = {}
    for rule in RULES:
        fns = line.functions(rule)
        for sign in (0, 1, -1):
            rel = (lambda L: 1.0) if sign == 0 else (lambda L, g=sign: 1.0 + g * line.s_err_at(L))
            f = rate(fns, tau_d_ratio)
            # the state is u = L − L*, the departure from this rule's steady pulse at τ_d: the
            # tolerance is then relative to the departure, which may be 1e-7 L* (e^{st} test)
            Le = line.equilibrium(tau_d_ratio, rule)

            def rhs(t, y, f=f, rel=rel, Le=Le):
                L = min(max(Le + y[0], lo), hi)
                return [f(L) * rel(L)]

            def short(t, y, Le=Le):
                return Le + y[0] - lo

            def long_(t, y, Le=Le):
                return Le + y[0] - hi
            short.terminal = long_.terminal = True
            sol = solve_ivp(rhs, (0.0, duration), [L0 - Le], method="LSODA", t_eval=t_out,
                            events=(short, long_), rtol=rtol, atol=1e-300)
            L = np.full(t_out.size, np.nan)
            L[:sol.t.size] = Le + sol.y[0]
            fate, t_f = "within the family", float("nan")
            for name, te in zip(("left the family (short end)", "left the family (long end)"),
                                sol.t_events):
                if te.size and (np.isnan(t_f) or te[0] < t_f):
                    fate, t_f = name, float(te[0])
            if not np.isnan(t_f):
                L[t_out > t_f] = np.nan
            out[(rule, sign)] = (L, fns[2](np.where(np.isfinite(L), L, L0)), fate, t_f)
    L, cp, fate, t_f = out[(RULES[0], 0)]
    cp = np.where(np.isfinite(L), cp, np.nan)
    Ls = np.array([v[0] for v in out.values()])
    Cs = np.array([np.where(np.isfinite(v[0]), v[1], np.nan) for v in out.values()])
    with np.errstate(invalid="ignore"), _quiet():
        L_lo, L_hi = np.nanmin(Ls, 0), np.nanmax(Ls, 0)
        c_lo, c_hi = np.nanmin(Cs, 0), np.nanmax(Cs, 0)
    ok = np.isfinite(L)
    x = np.full(t_out.size, np.nan)
    x[ok] = np.concatenate([[0.0], np.cumsum(0.5 * (cp[ok][1:] + cp[ok][:-1]) * np.diff(t_out[ok]))])
    L_eq = line.equilibrium(tau_d_ratio)
    s_eq = float(line.functions()[3](L_eq))
    info = {"tau_d_ratio": float(tau_d_ratio), "L0": float(L0), "duration": float(duration),
            "L_equilibrium": L_eq, "s_equilibrium": s_eq,
            "variant_fates": "; ".join(f"{r} s{'+-'[g < 0] if g else ''}{'err' if g else ''}: "
                                       f"{v[2]}" + (f" at {v[3]:.6g} s" if np.isfinite(v[3]) else "")
                                       for (r, g), v in out.items()),
            "rules": ",".join(RULES), "rtol": rtol,
            "L_range_min": lo, "L_range_max": hi, "n_pulses": int(line.L.size),
            "n_rated": int(line.L_rated.size), "source": line.source,
            "wall_time": time.perf_counter() - wall0, "cpu_time": time.process_time() - cpu0}
    return Trajectory(t_out, L, L_lo, L_hi, cp, c_lo, c_hi, x, fate, t_f, info)


class _quiet:
    """Silence numpy's warning for all-nan columns (a time after every variant left the family)."""

    def __enter__(self):
        import warnings
        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *a):
        return self._w.__exit__(*a)


def write_trajectory(path: str, traj: Trajectory, line: SteadyLine) -> None:
    """Write the trajectory (coordinate ``t``) and the run's parameters as attributes, atomically,
    replacing ``path`` (xarray: ``open_dataset(path, engine="h5netcdf")``)."""
    from ..core.h5io import atomic_update, coordinate, describe, stamp_format

    def fill(h5):
        stamp_format(h5, "motion")
        tc = coordinate(h5, "t", traj.t, units="s", long_name="time since the start")
        cols = {"L": ("m", "pulse length (FWHM of ln(v/v*+1)), model of record"),
                "L_lo": ("m", "lower edge of the band of L (s +- s_err, spline/PCHIP)"),
                "L_hi": ("m", "upper edge of the band of L"),
                "c_p": ("m/s", "pulse speed c_p0(L(t)) on the steady line"),
                "c_p_lo": ("m/s", "lower edge of the band of c_p"),
                "c_p_hi": ("m/s", "upper edge of the band of c_p"),
                "x": ("m", "distance travelled")}
        for k, (u, ln) in cols.items():
            describe(h5.create_dataset(k, data=getattr(traj, k)), u, ln, (tc,))
        h5.attrs["equation"] = "dL/dt = s(L) (tau0(L) - tau_d) / (dtau0/dL); c_p = c_p0(L)"
        h5.attrs["fate"] = traj.fate
        h5.attrs["t_fate"] = traj.t_fate
        h5.attrs["t_fate_units"] = "s"
        h5.attrs["tau_min"] = line.tau_min
        h5.attrs["tau_min_units"] = "Pa"
        h5.attrs["c_s"] = line.c_s
        h5.attrs["c_s_units"] = "m/s"
        for k, v in traj.info.items():
            h5.attrs[k] = v
        for k in ("L0", "L_equilibrium", "L_range_min", "L_range_max"):
            h5.attrs[f"{k}_units"] = "m"
        h5.attrs["s_equilibrium_units"] = "1/s"
        h5.attrs["duration_units"] = "s"
    atomic_update(path, fill, replace=True)


@dataclass
class Comparison:
    """A measured trajectory against the model started from its first state."""

    t: np.ndarray                 # s, the measurement times
    L: np.ndarray                 # m, measured
    c_p: np.ndarray               # m/s, measured (smoothed)
    x: np.ndarray                 # m, measured distance travelled
    model: Trajectory             # on the same times
    t_split: float                # s: first time L or c_p differ by more than tol (nan: never)
    distance_split: float         # L0 travelled by then (nan: never)
    line_distance: np.ndarray     # c_p/c_p⁰(L) − 1 of the measurement (nan off the family)
    tol: float
    skip: int                     # the sample the model starts from
    distance_split_L: float = float("nan")   # L0 travelled when L alone first differs by tol
    distance_split_c: float = float("nan")   # ... c_p alone


def smoothed_speed(t, x, k: int = 5):
    """c_p from the front positions: the slope over ±k//2 samples (central, one-sided at the
    ends), as the fate runs' front moves by whole cells between samples."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    h = max(1, k // 2)
    i = np.arange(t.size)
    a, b = np.clip(i - h, 0, t.size - 1), np.clip(i + h, 0, t.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (x[b] - x[a]) / (t[b] - t[a])


def compare(line: SteadyLine, tau_d_ratio: float, t, x_front, L, tol: float = 0.05,
            skip: int | None = None, start: float = 0.01) -> Comparison:
    """The model from the measured L at sample ``skip``, on the measured times; the first time
    after it at which |L_model/L − 1| or |c_p,model/c_p − 1| exceeds ``tol``, and how far the
    measured pulse had travelled by then (in its first length).

    Default ``skip``: the first sample whose L departs from the steady L* at τ_d by ``start``
    (relative). A seeded pulse starts ε·(mode) away from L*, a departure of 1e-4 L* or less, which
    the FWHM on the SBI grid does not resolve: started there, the model follows the sign of the
    grid's error. ValueError if L never departs by ``start``."""
    t, x_front, L = (np.asarray(a, float) for a in (t, x_front, L))
    cp = smoothed_speed(t, x_front)
    if skip is None:
        L_eq = line.equilibrium(tau_d_ratio)
        far = np.flatnonzero(np.abs(L / L_eq - 1.0) >= start)
        if far.size == 0:
            raise ValueError(f"L never departs from L* = {L_eq:.5g} m by {start:g}")
        skip = int(far[0])
    t0 = t[skip]
    tr = integrate(line, tau_d_ratio, float(L[skip]), float(t[-1] - t0), n_out=400)
    tm = tr.t + t0
    Lm = np.interp(t, tm, tr.L, left=np.nan, right=np.nan)
    cm = np.interp(t, tm, tr.c_p, left=np.nan, right=np.nan)
    gone = (t > t0) & ~np.isfinite(Lm) & np.isfinite(L)   # the model left the family, not the pulse
    with np.errstate(invalid="ignore"):
        bad_L = (np.abs(Lm / L - 1) > tol) | gone
        bad_c = (np.abs(cm / cp - 1) > tol) | gone
    bad_L[:skip] = bad_c[:skip] = False

    def first(bad):
        k = np.flatnonzero(bad)
        return (float(t[k[0]]), float((x_front[k[0]] - x_front[0]) / L[0])) if k.size else \
            (float("nan"), float("nan"))
    t_split, d_split = first(bad_L | bad_c)
    d_L, d_c = first(bad_L)[1], first(bad_c)[1]
    lo, hi = line.L_range
    fns = line.functions()
    on = (L >= lo) & (L <= hi)
    dist = np.full(t.size, np.nan)
    dist[on] = cp[on] / fns[2](L[on]) - 1.0
    model = Trajectory(t, Lm, np.interp(t, tm, tr.L_lo, left=np.nan, right=np.nan),
                       np.interp(t, tm, tr.L_hi, left=np.nan, right=np.nan), cm,
                       np.interp(t, tm, tr.c_p_lo, left=np.nan, right=np.nan),
                       np.interp(t, tm, tr.c_p_hi, left=np.nan, right=np.nan),
                       np.interp(t, tm, tr.x, left=np.nan, right=np.nan), tr.fate,
                       tr.t_fate + t0 if np.isfinite(tr.t_fate) else tr.t_fate, tr.info)
    return Comparison(t, L, cp, x_front - x_front[0], model, t_split, d_split, dist, tol, skip,
                      d_L, d_c)


# ------------------------------------------------------------------ where the model ends
def read_tables(paths):
    """The steady line of the family's committed tables (CSV columns ``tau_d_ratio``, ``beta``,
    ``L``; e.g. steady/seeds/deep_family_*.csv, 1 m – 10 km): (L, τ⁰/τ_min, β) sorted by L, each
    table's rows kept only beyond the L already covered (overlapping marches) and a row whose τ
    does not fall with L dropped, so that the line is a function of L."""
    import csv
    rows = []
    for p in paths:
        with open(p, newline="") as fh:
            part = sorted((float(r["L"]), float(r["tau_d_ratio"]), float(r["beta"]))
                          for r in csv.DictReader(fh))
        top = rows[-1][0] if rows else -np.inf
        rows += [r for r in part if r[0] > top]
    rows.sort()
    keep = [rows[0]]
    for r in rows[1:]:
        if r[0] > keep[-1][0] and r[1] < keep[-1][1]:
            keep.append(r)
    a = np.array(keep)
    return a[:, 0], a[:, 1], a[:, 2]


def line_from_tables(tables, records, params=None) -> SteadyLine:
    """A steady line from the family's tables (:func:`read_tables`) and the growth rates of
    record (``spectrum.records.read_rates``: s L/c_p ± err at L), s = (s L/c_p)·c_p⁰(L)/L with
    c_p⁰ interpolated in ln L. Rates outside the tables' L range (by more than 1e-4, the rounding
    of the records' L) are dropped."""
    from ..core.params import DEFAULT
    from ..spectrum.records import read_rates
    p = params or DEFAULT
    L, tau, beta = read_tables([str(t) for t in tables])
    r = read_rates(str(records))
    inside = (r["L"] >= L[0] * (1 - 1e-4)) & (r["L"] <= L[-1] * (1 + 1e-4))   # labels' rounding
    Lr = r["L"][inside]
    cp = np.interp(np.log(Lr), np.log(L), beta) * p.c_s
    return SteadyLine.from_arrays(L, tau, beta * p.c_s, Lr, r["s"][inside] * cp / Lr,
                                  r["s_err"][inside] * cp / Lr, tau_min=p.tau_min, c_s=p.c_s,
                                  source=", ".join([*map(str, tables), str(records)]))


@dataclass
class Limits:
    """What the model says beyond the family's range and where it stops describing a pulse."""

    tau_d_ratio: float
    L_equilibrium: float          # m
    L: np.ndarray                 # m, a grid from L* (growing side) to the long end
    rate: np.ndarray              # m/s, dL/dt of the model on that grid
    mobility: np.ndarray          # R(L) = s L/c_p⁰ / |dτ⁰/d ln L|: dL/dt = R c_p⁰ (τ_d − τ⁰)
    healing_speed: np.ndarray     # m/s, c_p⁰ − dL/dt: the rear front's lab speed in the model
    time: np.ndarray              # s, ∫ dL/(dL/dt) from the first grid point (L*(1 + start))
    L_heal_stops: float           # m, first L where the rear front stops (nan: never)
    L_heal_moves: float           # m, first L beyond that where it moves forward again (nan)
    exponent_end: float           # p: dL/dt ∝ L^p over the last tenth of the grid in ln L
    t_end: float                  # s, time to reach the long end
    t_rest: float                 # s, time from the end to L = ∞ if dL/dt ∝ L^p beyond (inf: p ≤ 1)
    finite_time_divergence: bool  # p > 1


def limits(line: SteadyLine, tau_d_ratio: float, start: float = 0.01, n: int = 4000,
           rule: str = "spline") -> Limits:
    """The growing side of the model under τ_d, from L*(1 + start) to the family's long end.

    Written with R = s L/c_p⁰ / |dτ⁰/d ln L| (the fold ratio of the spectrum),
    dL/dt = R(L) c_p⁰(L) (τ_d − τ⁰(L)). Two consequences, both read off the family:

    * *no finite-time divergence while R stays bounded*: c_p⁰ < c_s and τ⁰ > τ⁰(∞), so
      dL/dt ≤ c_s (τ_d − τ⁰(∞)) sup R and L grows at most linearly; L diverges in finite time
      only if dL/dt grows faster than L (∫^∞ dL/(dL/dt) < ∞). The local exponent p of dL/dt
      in L at the long end, extended beyond it, gives the time left to L = ∞ (finite iff p > 1).
    * *where it stops describing a pulse*: in the two-front picture the rear (healing) front
      moves at c_p⁰ − dL/dt in the lab; where that reaches 0 the rear stops, and beyond it
      would move backward, an expanding crack, which a family of pulses cannot hold.

    MotionInputError for τ_d outside the family's range."""
    lo, hi = line.L_range
    tlo, thi = line.tau_range
    if not (np.isfinite(tau_d_ratio) and tlo <= tau_d_ratio <= thi):
        raise MotionInputError(f"tau-d={tau_d_ratio!r} is outside the family: valid "
                               f"[{tlo:.6g}, {thi:.6g}] tau_min")
    Le = line.equilibrium(tau_d_ratio, rule)
    L0 = Le * (1.0 + start)
    if not L0 < hi:
        raise MotionInputError(f"L*(1 + start) = {L0:.5g} m is beyond the family's long end")
    tau, dtau, cp, s = line.functions(rule)
    L = np.geomspace(L0, hi, n)
    F = rate((tau, dtau, cp, s), tau_d_ratio)(L)
    with np.errstate(divide="ignore", invalid="ignore"):
        R = s(L) * L / cp(L) / np.abs(dtau(L) * L)
    heal = cp(L) - F
    # t(L) = ∫ dL/F in ln L (trapezoid on a fine geometric grid; F > 0 on the growing side)
    g = L / F
    time = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(np.log(L)))])
    stop = np.flatnonzero(heal <= 0)
    L_stop = float(L[stop[0]]) if stop.size else float("nan")
    L_move = float("nan")
    if stop.size:
        again = np.flatnonzero((heal > 0) & (np.arange(L.size) > stop[0]))
        L_move = float(L[again[0]]) if again.size else float("nan")
    # the local exponent over the last tenth of the grid in ln L
    k = L >= L[-1] * (L0 / L[-1]) ** 0.1
    p = float(np.polyfit(np.log(L[k]), np.log(F[k]), 1)[0])
    t_rest = float(L[-1] / ((p - 1.0) * F[-1])) if p > 1 else float("inf")
    return Limits(float(tau_d_ratio), Le, L, F, R, heal, time, L_stop, L_move, p,
                  float(time[-1]), t_rest, p > 1)
