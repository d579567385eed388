"""Where steady pulses exist, and where the solver finds them, over two friction groups (b, α).

At fixed τ_d/τ_min (default 1.2) and the other parameters fixed (default Table I), each point
(b, α) of a grid is classified:

1. ``n_shape``: whether τ_ss(v) has its N shape (a local maximum, then a minimum below c_s) and
   τ_d lies below the local maximum (else no stick state: no self-healing pulse can exist);
2. ``guess``: a solve from the built-in guess (:func:`slippulse.steady.solver.solve_pulse`);
3. ``cont``: a solve by continuation in the parameters, from an already-solved neighbour of the
   grid (breadth-first from the grid point nearest to ``start``, each point seeded with the
   converged pulse of a neighbour; one intermediate point (b, α geometric means) is tried when the
   direct step fails).

A solve *finds the pulse* when Newton converges (max|Δ| ≤ tol), the solution has one hump
(:func:`count_humps`), 0 < β < 1 and a finite FWHM length L. Otherwise the reason is recorded:
``newton: <message>`` (no convergence), ``humps=<n>`` (converged to a bound state or a non-pulse),
``no length`` (L not measurable), or the exception's one-line text.

The result (:class:`ExistenceMap`) holds arrays over (b, α): status codes, β, L, L/L0, L̃ and the
reasons; :func:`write_map` stores it in HDF5 with its parameters (netCDF conventions, xarray).
"""
from __future__ import annotations

import dataclasses as dc
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..core.params import DEFAULT, ParameterError, Parameters
from .param_continuation import as_guess as _as_guess
from .param_continuation import attempt as _attempt

#: Status codes of a point.
NO_N_SHAPE, ABOVE_PEAK, FAILED, FOUND, NOT_TRIED = 0, 1, 2, 3, 4
STATUS_NAMES = {NO_N_SHAPE: "no N shape", ABOVE_PEAK: "tau_d >= local max",
                FAILED: "solver failed", FOUND: "pulse found", NOT_TRIED: "not tried"}


@dataclass
class ExistenceMap:
    """Classification of a (b, α) grid (arrays indexed [i_b, i_alpha])."""

    b: np.ndarray
    alpha: np.ndarray
    tau_d_ratio: float
    base: Parameters
    n_points: int
    shape_status: np.ndarray          # FOUND where N-shaped with τ_d below the peak, else the code
    peak_ratio: np.ndarray            # τ_peak/τ_min (NaN without N shape)
    guess_status: np.ndarray
    cont_status: np.ndarray
    beta: np.ndarray                  # from the guess solve, else from continuation (NaN: none)
    L: np.ndarray
    L_over_L0: np.ndarray
    L_tilde: np.ndarray
    guess_reason: np.ndarray          # object arrays of str
    cont_reason: np.ndarray
    shape_reason: np.ndarray
    agree: np.ndarray                 # |Δβ|/β between guess and continuation where both found
    wall_time: float = 0.0
    solves: int = 0
    log: list = field(default_factory=list)


def point_params(base: Parameters, b: float, alpha: float) -> Parameters:
    """``base`` with (b, α) replaced (may raise ParameterError: f0 b ≤ α)."""
    return dc.replace(base, b=float(b), alpha=float(alpha))


def classify_shape(base: Parameters, b: float, alpha: float, tau_d_ratio: float):
    """(status, τ_peak/τ_min, reason, params or None) of the friction curve at (b, α)."""
    try:
        p = point_params(base, b, alpha)
        ratio = p.tau_peak / p.tau_min
    except ParameterError as exc:
        return NO_N_SHAPE, math.nan, str(exc), None
    if tau_d_ratio >= ratio:
        return (ABOVE_PEAK, ratio, f"tau_d/tau_min={tau_d_ratio:g} >= tau_peak/tau_min="
                f"{ratio:.4g}: no stick state", p)
    return FOUND, ratio, "", p


@dataclass(frozen=True)
class PointSolve:
    """The outcome of one solve of the map, as a task returns it: found or not, the reason, the
    measures of the pulse (β, L, L/L0, L̃) and its state as a start for a neighbour."""

    ok: bool
    why: str
    measures: tuple = ()
    start: tuple | None = None          # (ξ, x without β, β): :func:`as_guess`

    def to_json(self):
        s = None if self.start is None else [np.asarray(a).tolist() if np.ndim(a) else float(a)
                                             for a in self.start]
        return {"ok": self.ok, "why": self.why, "measures": list(self.measures), "start": s}

    @classmethod
    def from_json(cls, d):
        s = None if d["start"] is None else (np.asarray(d["start"][0]), np.asarray(d["start"][1]),
                                             float(d["start"][2]))
        return cls(bool(d["ok"]), str(d["why"]), tuple(d["measures"]), s)


def _outcome(p, sol, ok, why):
    if not ok:
        return PointSolve(False, why)
    pulse = sol.to_pulse()
    return PointSolve(True, why, (pulse.beta, pulse.L, pulse.L / p.L0, pulse.L_tilde),
                      _as_guess(sol))


def solve_from_guess(p, tau_d_ratio, n_points):
    """One point from the built-in guess (a task of the map)."""
    return _outcome(p, *_attempt(p, tau_d_ratio, n_points))


def solve_from_neighbour(p, mid, tau_d_ratio, n_points, start):
    """One point from a solved neighbour's state `start`; where that fails, through `mid` (the
    geometric mean of the two points' (b, α), or None) first (a task of the map)."""
    sol, ok, why = _attempt(p, tau_d_ratio, n_points, guess=start)
    n = 1
    if not ok and mid is not None:
        s_mid, ok_mid, _ = _attempt(mid, tau_d_ratio, n_points, guess=start)
        n += 1
        if ok_mid:
            sol, ok, why2 = _attempt(p, tau_d_ratio, n_points, guess=_as_guess(s_mid))
            n += 1
            why = why2 if not ok else ""
    return _outcome(p, sol, ok, why), n


class _Checkpoint:
    """The solves done so far, by task key, in a JSON file beside the map (rewritten atomically
    after each): a rerun of the same map reads them back instead of solving again."""

    def __init__(self, path, key):
        import json
        import os
        self.path, self.key, self.done = path, key, {}
        if path and os.path.exists(path):
            try:
                with open(path, encoding="utf-8") as fh:
                    d = json.load(fh)
                if d.get("key") == key:
                    self.done = d["solves"]
            except (OSError, ValueError, KeyError):
                self.done = {}

    def get(self, k):
        return self.done.get(k)

    def put(self, k, value):
        import json

        from ..core.atomic import replacing_open
        self.done[k] = value
        if self.path:
            with replacing_open(self.path, "w") as fh:
                json.dump({"key": self.key, "solves": self.done}, fh)


def _run(pool, cp, tasks):
    """{key: result} of `tasks` ({key: (fn, args)}), read from the checkpoint `cp` or solved on
    `pool` (each written to `cp` as it arrives)."""
    out = {}
    handles = {}
    for k, (fn, args) in tasks.items():
        got = cp.get(k)
        if got is not None:
            out[k] = got
        else:
            handles[pool.submit(fn, *args)] = k
    for h, value, err in pool.completed():
        k = handles.pop(h)
        if err is not None:
            raise err
        value = value.to_json() if isinstance(value, PointSolve) else \
            [value[0].to_json(), value[1]]
        cp.put(k, value)
        out[k] = value
    return out


def existence_map(b_values, alpha_values, tau_d_ratio: float = 1.2, base: Parameters = DEFAULT,
                  n_points: int = 500, start: tuple | None = None, guess: bool = True,
                  continuation: bool = True, progress=None, executor=None,
                  checkpoint: str | None = None) -> ExistenceMap:
    """Classify each (b, α) of the grid (see the module docstring).

    Parameters
    ----------
    b_values, alpha_values : sequences of float
        Grid of the state coefficient b and the rate-strengthening coefficient α.
    tau_d_ratio : float
        Fixed τ_d/τ_min.
    base : Parameters
        The other parameters.
    n_points : int
        Grid points of every solve (≥ 500 at 1.2 τ_min for Table I; 400 does not converge).
    start : (b, α), optional
        Where continuation starts (default: ``(base.b, base.alpha)``); the nearest grid point (in
        log) is solved from the built-in guess and continuation spreads from it in waves: each
        wave solves, at once, every point next to one solved in the wave before (from that
        neighbour; a point is tried from at most two neighbours).
    guess, continuation : bool
        Which of the two solves to run.
    progress : callable(str), optional
        Told about each solve.
    executor : :class:`slippulse.core.executor.ExecutorSettings`, optional
        Where the independent solves (all the guess solves; the solves of one wave) run
        (default: this process). The map is the same whichever runs them.
    checkpoint : str, optional
        A JSON file that keeps each solve as it arrives; a rerun of the same map (grid,
        parameters, N) goes on from it.
    """
    from ..core.executor import TaskPool
    t0 = time.perf_counter()
    m, prm = _classified(b_values, alpha_values, tau_d_ratio, base, n_points)
    b, a = m.b, m.alpha
    cp = _Checkpoint(checkpoint, f"{b.tolist()} {a.tolist()} {tau_d_ratio!r} {n_points} "
                                 f"{sorted(base.as_dict().items())}")

    def record(k, res):
        m.beta[k], m.L[k], m.L_over_L0[k], m.L_tilde[k] = res["measures"]

    def say(msg):
        m.log.append(msg)
        if progress:
            progress(msg)

    guess_beta = {}
    with TaskPool(executor) as pool:
        if guess:
            done = _run(pool, cp, {f"guess {i} {j}": (solve_from_guess, (p, tau_d_ratio,
                                                                           n_points))
                                   for (i, j), p in prm.items()})
            for (i, j) in prm:
                res = done[f"guess {i} {j}"]
                m.solves += 1
                m.guess_status[i, j] = FOUND if res["ok"] else FAILED
                m.guess_reason[i, j] = res["why"]
                if res["ok"]:
                    record((i, j), res)
                    guess_beta[i, j] = res["measures"][0]
                say(f"guess b={b[i]:g} alpha={a[j]:g}: {'found' if res['ok'] else res['why']}")
        if continuation and prm:
            _continuation(m, prm, pool, cp, start, guess_beta, record, say)
    m.wall_time = time.perf_counter() - t0
    return m


def _classified(b_values, alpha_values, tau_d_ratio, base, n_points):
    """An :class:`ExistenceMap` with the shape classes filled in, and {(i, j): params} of the
    points where a pulse can exist."""
    b = np.asarray(b_values, float)
    a = np.asarray(alpha_values, float)
    shape = (b.size, a.size)
    nan = lambda: np.full(shape, np.nan)
    obj = lambda: np.full(shape, "", dtype=object)
    m = ExistenceMap(b=b, alpha=a, tau_d_ratio=float(tau_d_ratio), base=base, n_points=n_points,
                     shape_status=np.zeros(shape, int), peak_ratio=nan(),
                     guess_status=np.full(shape, NOT_TRIED), cont_status=np.full(shape, NOT_TRIED),
                     beta=nan(), L=nan(), L_over_L0=nan(), L_tilde=nan(), guess_reason=obj(),
                     cont_reason=obj(), shape_reason=obj(), agree=nan())
    prm = {}
    for i in range(b.size):
        for j in range(a.size):
            st, ratio, why, p = classify_shape(base, b[i], a[j], tau_d_ratio)
            m.shape_status[i, j], m.peak_ratio[i, j], m.shape_reason[i, j] = st, ratio, why
            if st != FOUND:
                m.guess_status[i, j] = m.cont_status[i, j] = st
                m.guess_reason[i, j] = m.cont_reason[i, j] = why
            else:
                prm[i, j] = p
    return m, prm


def _continuation(m, prm, pool, cp, start, guess_beta, record, say):
    """Continuation in (b, α) from the point nearest `start`, in waves (see existence_map)."""
    b, a, base = m.b, m.alpha, m.base
    tau, n_points = m.tau_d_ratio, m.n_points
    sb, sa = (base.b, base.alpha) if start is None else start
    dist = {k: abs(math.log(b[k[0]] / sb)) + abs(math.log(a[k[1]] / sa)) for k in prm}
    first = min(dist, key=dist.get)
    res = _run(pool, cp, {"start": (solve_from_guess, (prm[first], tau, n_points))})["start"]
    m.solves += 1
    m.cont_status[first] = FOUND if res["ok"] else FAILED
    m.cont_reason[first] = "start (built-in guess)" if res["ok"] else f"start: {res['why']}"
    solved = {first: res} if res["ok"] else {}
    tries = {first: 2}
    wave = [first] if res["ok"] else []
    while wave:
        tasks, sources = {}, {}
        for (i, j) in wave:
            for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                k = (i + di, j + dj)
                if k not in prm or k in solved or k in sources or tries.get(k, 0) >= 2:
                    continue        # at most two neighbours are tried as the source of a point
                tries[k] = tries.get(k, 0) + 1
                mid = point_params(base, math.sqrt(b[i] * b[k[0]]), math.sqrt(a[j] * a[k[1]]))
                try:
                    mid.tau_min
                except ParameterError:
                    mid = None
                src = solved[i, j]["start"]
                start_k = (np.asarray(src[0]), np.asarray(src[1]), float(src[2]))
                key = f"cont {k[0]} {k[1]} from {i} {j}"
                tasks[key] = (solve_from_neighbour, (prm[k], mid, tau, n_points, start_k))
                sources[k] = ((i, j), key)
        done = _run(pool, cp, tasks)
        wave = []
        for k, ((i, j), key) in sources.items():
            res, n = done[key]
            m.solves += n
            ok = res["ok"]
            m.cont_reason[k] = f"from b={b[i]:g} alpha={a[j]:g}" if ok else res["why"]
            m.cont_status[k] = FOUND if ok else FAILED
            say(f"cont  b={b[k[0]]:g} alpha={a[k[1]]:g} from ({b[i]:g}, {a[j]:g}): "
                f"{'found' if ok else res['why']}")
            if ok:
                solved[k] = res
                wave.append(k)
                if k in guess_beta:
                    m.agree[k] = abs(res["measures"][0] / guess_beta[k] - 1.0)
                else:
                    record(k, res)
    if first in solved and first in guess_beta:
        m.agree[first] = abs(solved[first]["measures"][0] / guess_beta[first] - 1.0)
    elif first in solved:
        record(first, solved[first])


def summary(m: ExistenceMap) -> str:
    """Counts of each outcome, one line."""
    n = m.b.size * m.alpha.size
    shp = int(np.sum(m.shape_status == FOUND))
    g = int(np.sum(m.guess_status == FOUND))
    c = int(np.sum(m.cont_status == FOUND))
    either = int(np.sum((m.guess_status == FOUND) | (m.cont_status == FOUND)))
    ag = m.agree[np.isfinite(m.agree)]
    return (f"{n} points: {shp} N-shaped with tau_d below the peak; pulse found from the guess at "
            f"{g}, by continuation at {c}, by either at {either}; guess vs continuation beta "
            f"agree to {ag.max():.1e}" if ag.size else "") + \
        f"; {m.solves} solves, {m.wall_time:.0f} s"


def write_map(path: str, m: ExistenceMap) -> None:
    """The map in HDF5 (dimensions b, alpha; parameters group; atomic)."""
    from ..core.h5io import atomic_update, coordinate, describe, stamp_format, write_parameters

    def fill(h5):
        stamp_format(h5, "slippulse-existence-map")
        write_parameters(h5, m.base)
        h5.attrs["tau_d_ratio"] = m.tau_d_ratio
        h5.attrs["n_points"] = m.n_points
        h5.attrs["wall_time"] = m.wall_time
        h5.attrs["solves"] = m.solves
        h5.attrs["status_codes"] = "; ".join(f"{k} = {v}" for k, v in STATUS_NAMES.items())
        db = coordinate(h5, "b", m.b, units="1", long_name="state coefficient b")
        da = coordinate(h5, "alpha", m.alpha, units="1",
                        long_name="rate-strengthening coefficient alpha")
        dims = (db, da)
        for name, units, long in (
                ("shape_status", "1", "N shape of tau_ss with tau_d below the peak (status code)"),
                ("guess_status", "1", "solve from the built-in guess (status code)"),
                ("cont_status", "1", "solve by continuation in (b, alpha) (status code)"),
                ("peak_ratio", "1", "tau_peak/tau_min"), ("beta", "1", "c_p/c_s"),
                ("L", "m", "pulse length (FWHM of ln(v/v*+1))"),
                ("L_over_L0", "1", "L/L0"), ("L_tilde", "1", "L tau_min^2/(mu G_c*)"),
                ("agree", "1", "|beta_cont/beta_guess - 1|")):
            arr = np.asarray(getattr(m, name), dtype=float if "status" not in name else np.int64)
            describe(h5.create_dataset(name, data=arr), units, long, dims=dims)
        for name in ("guess_reason", "cont_reason", "shape_reason"):
            h5.create_dataset(name, data=np.asarray(getattr(m, name), dtype=str).astype("S"))

    atomic_update(path, fill, replace=True)


def read_map(path: str) -> ExistenceMap:
    """An :class:`ExistenceMap` back from :func:`write_map`'s file (log not stored)."""
    from ..core.h5io import open_h5, read_parameters

    with open_h5(path, "map") as h5:
        arr = lambda k: np.asarray(h5[k][...])
        txt = lambda k: np.asarray([[s.decode() for s in row] for row in h5[k][...]], dtype=object)
        return ExistenceMap(
            b=arr("b"), alpha=arr("alpha"), tau_d_ratio=float(h5.attrs["tau_d_ratio"]),
            base=read_parameters(h5), n_points=int(h5.attrs["n_points"]),
            shape_status=arr("shape_status"), peak_ratio=arr("peak_ratio"),
            guess_status=arr("guess_status"), cont_status=arr("cont_status"), beta=arr("beta"),
            L=arr("L"), L_over_L0=arr("L_over_L0"), L_tilde=arr("L_tilde"),
            guess_reason=txt("guess_reason"), cont_reason=txt("cont_reason"),
            shape_reason=txt("shape_reason"), agree=arr("agree"),
            wall_time=float(h5.attrs["wall_time"]), solves=int(h5.attrs.get("solves", 0)))
