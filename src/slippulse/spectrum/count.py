"""A count of the unstable eigenvalues of a pulse by the argument principle (docs/spectrum.md §5).

M(σ) (:class:`slippulse.spectrum.pulse.StabilityOperator`) is analytic in Re σ > 0, so det M(σ)
has no poles there and the number of its zeros inside a closed contour C in that half-plane is the
winding number of det M along C:

    Z = (1/2π) Δ_C arg det M(σ).

arg det M and ln|det M| come from the LU factors (Σ arg u_ii plus π per row interchange,
Σ ln|u_ii|). The contour is the rectangle x0 ≤ Re σ ≤ x1, |Im σ| ≤ y1 (in units of c_p/L), walked
counter-clockwise. With g = d ln det M/dσ = tr(M⁻¹ M′(σ)) (Jacobi's formula) at every point,
the change of ln det M between neighbours a, b is predicted by the trapezoid
T = ½ (g_a + g_b)(σ_b − σ_a). The change of arg det is read as the wrapped difference of the two
arguments plus the multiple of 2π nearest to Im T (the branch). Points are inserted between
neighbours until, for every pair,

- the change of g across the segment, |g_b − g_a| |σ_b − σ_a|, is below ``max_step``, and
- the change of arg det so read agrees with Im T within ``max_step`` radians, and
- the change of ln|det M| (which has no branch) agrees with Re T within ``max_step``.

A zero at a distance d from a segment of length h ≫ d adds 1/(σ − λ) to g, whose change across
the segment is about 4/h at least (h/d when it is near an end): the segment is halved until h is
of the order of d, where the trapezoid follows the zero's turn. The zeros far from the segment
add to g a large (N of them) but smooth part, which the trapezoid integrates: at the deep pulses
(N = 2828, L = 1.8 km) |g| ≈ 60–650 (c_p/L)⁻¹ along the whole contour, so the phase turns by
≈ 60 rad per unit of σ L/c_p, smoothly. The older rule also required the wrapped change
itself to be below ``max_step`` (``phase_rule='wrapped'``): one point per 0.01 c_p/L of contour
there, ≈ 2400 evaluations for a box of ±4 c_p/L, against ≈ 300 for the rule above. Every pair the
old rule accepts, the new one accepts with the same change (|Im T| < 2 max_step < π picks the
branch 0), save for the ln|det M| check, which the old rule did not make.

Without M′ (``derivative=False``, or an operator whose ``matrices`` gives none) the walk can only
require the wrapped change to be below ``max_step``. That alone cannot see a zero closer to the
contour than the spacing (the phase jumps by about π within the zero's own distance, and two
such jumps hide a turn of 2π between two evaluations), nor a steady drift faster than 2π per
spacing (the discrete continuum just left of the left edge drives one; at 1.025 τ_min, −4.5 rad
per unit of Im σ L/c_p): both alias to small wrapped changes (``reach`` is then nan).

The sum of the changes must be within ``integer_tol`` of an integer multiple of 2π. A walk that
does not meet the conditions within ``max_evals`` evaluations reports status 'failed' and no
count.

The pulse operators have real coefficients, M(σ̄) = conj M(σ): arg det M(σ̄) = −arg det M(σ),
g(σ̄) = conj g(σ), and the box is symmetric about the real axis, so one determinant on Im σ ≥ 0
serves both halves (``conjugate_symmetric`` on the operator), half the cost.

A walk at the deep pulses costs tens of minutes to hours (one evaluation assembles an N × N kernel
matrix and factors it: ≈ 10 s at N = 2828 with the tail segments by Filon–Gauss; the dense LU and its N right-hand sides grow as N³ beyond). With a ``checkpoint`` file the evaluations survive an interruption or an exhausted
budget: each (σ, arg det M, ln|det M|, g) is kept, the file is rewritten atomically as the walk goes, and a
rerun on the same operator (:func:`operator_key`) reads them back instead of evaluating again.
The walk is deterministic, so the resumed walk visits the same points and ends as an
uninterrupted one would; evaluations at σ on another box of the same operator are reused too.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import eigvals, hankel, lu_factor, lu_solve

from ..core.atomic import replacing_open


def _lu_log_det(lu, piv) -> tuple[float, float]:
    d = np.diag(lu)
    swaps = int(np.count_nonzero(piv != np.arange(piv.size)))
    arg = float(np.sum(np.angle(d))) + math.pi * swaps
    return float(np.sum(np.log(np.abs(d)))), math.remainder(arg, 2.0 * math.pi)


def arg_det(M) -> tuple[float, float]:
    """(ln|det M|, arg det M ∈ (−π, π]) from the LU factorisation of M."""
    return _lu_log_det(*lu_factor(M, check_finite=False))


def log_det_derivative(M, dM, with_abs=False):
    """(arg det M, d ln det M/dσ = tr(M⁻¹ M′)) from one LU factorisation of M (Jacobi's formula);
    with_abs: (arg, g, ln|det M|)."""
    lu = lu_factor(M, check_finite=False)
    la, arg = _lu_log_det(*lu)
    g = complex(np.trace(lu_solve(lu, dM, check_finite=False)))
    return (arg, g, la) if with_abs else (arg, g)


def _wrap(x):
    return math.remainder(x, 2.0 * math.pi)


@dataclass
class ContourCount:
    """Result of :func:`count_unstable`: Z zeros of det M inside the box (units c_p/L)."""

    count: int | None
    winding: float                   # (1/2π) Σ Δarg (an integer up to the walk's error)
    box: tuple                       # (x0, x1, y1) in c_p/L
    n_evals: int
    max_step: float                  # largest |Δarg| between neighbours after refinement, rad
    status: str
    message: str
    wall_time: float
    points: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))   # σ L/c_p walked
    args: np.ndarray = field(default_factory=lambda: np.zeros(0))              # unwrapped arg det
    reach: float = float("nan")      # largest derivative criterion between neighbours (nan: none)
    resumed: int = 0                 # evaluations of this walk read from the checkpoint
    checkpoint_note: str = ""        # why a checkpoint file present was not used ('' otherwise)
    log_abs: np.ndarray = field(default_factory=lambda: np.zeros(0))   # ln|det M| at the points
    g: np.ndarray | None = None      # d ln det M/dσ (units L/c_p) at the points; None: walked without
    located: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))  # zeros polished inside


def operator_key(op) -> str:
    """What identifies the operator of a count checkpoint: its size, pulse and parameters.

    β, L and τ_d to 12 significant digits (a pulse re-solved with another thread count differs
    in the last bits; two pulses of a family differ far above 1e-12), the translation pin, the
    kernel's quadrature rule (``kernel``: far segments by Filon–Gauss, or split on both sides), and the friction and elastic parameters. An operator without a pulse (a
    test matrix) gives its class name and any ``key`` attribute.
    """
    pulse = getattr(op, "pulse", None)
    if pulse is None:
        return f"{type(op).__name__}:{getattr(op, 'key', '')}"
    params = getattr(op, "params", None)
    pdict = params.as_dict() if params is not None else {}
    ptext = ",".join(f"{k}={float(v):.12g}" for k, v in sorted(pdict.items())
                     if isinstance(v, (int, float)))
    split = getattr(getattr(op, "elastic", None), "split_per_side", None)
    return (f"N={int(pulse.n_points)} beta={float(pulse.beta):.12g} L={float(pulse.L):.12g} "
            f"tau_d={float(pulse.tau_d):.12g} pin={int(getattr(op, 'pin', None) is not None)} "
            + ("" if split is None else f"kernel={'filon' if split else 'split-both'} ")
            + f"{ptext}")


def read_checkpoint(path, key):
    """({σ: (arg, g or None, ln|det|)}, note) from a checkpoint file; an absent file gives ({}, ''),
    one written for another operator or unreadable gives ({}, why) and is overwritten later."""
    if not path or not os.path.exists(path):
        return {}, ""
    try:
        with np.load(path, allow_pickle=False) as f:
            stored = str(f["key"])
            z, a, g, la = f["z"], f["arg"], f["g"], f["logabs"]
    except Exception as exc:               # a foreign or damaged file: not ours to trust
        return {}, f"checkpoint {path} unreadable ({type(exc).__name__}); starting afresh"
    if stored != key:
        return {}, f"checkpoint {path} is for another operator ({stored}); starting afresh"
    return ({complex(zk): (float(ak), None if np.isnan(gk) else complex(gk), float(lk))
             for zk, ak, gk, lk in zip(z, a, g, la)}, "")


def write_checkpoint(path, key, cache):
    """Every evaluation in `cache`, written atomically (:func:`slippulse.core.atomic.replacing`:
    an interrupted write leaves the previous checkpoint)."""
    z = np.array(list(cache), complex)
    a = np.array([v[0] for v in cache.values()], float)
    g = np.array([np.nan if v[1] is None else v[1] for v in cache.values()], complex)
    la = np.array([v[2] for v in cache.values()], float)
    with replacing_open(path, "wb") as fh:
        np.savez(fh, key=np.array(key), z=z, arg=a, g=g, logabs=la)


def det_values(op, z):
    """(arg det M, g in units of (c_p/L)⁻¹ or None, ln|det M|) at z (units of c_p/L): one task
    of a walk on the executor (the operator is placed on each worker once)."""
    M, dM = op.matrices(z * op.rate_unit, deriv=True)
    if dM is None:
        la, a = arg_det(M)
        return a, None, la
    a, g, la = log_det_derivative(M, dM, with_abs=True)
    return a, g * op.rate_unit, la


def _rectangle(x0, x1, y1, per_side, symmetric=False):
    """Counter-clockwise corners-and-edges of the box, closed (last point = first).

    symmetric: each point below the real axis is replaced by the exact conjugate of its partner
    above (the two differ in the last bits otherwise), so that the midpoints of mirrored pairs
    are exact conjugates too; the points above are those of the plain rectangle."""
    corners = [complex(x0, -y1), complex(x1, -y1), complex(x1, y1), complex(x0, y1)]
    pts = []
    for a, b in zip(corners, corners[1:] + corners[:1]):
        t = np.linspace(0.0, 1.0, per_side, endpoint=False)
        pts.extend(complex(p) for p in a + (b - a) * t)
    pts.append(corners[0])
    if symmetric:
        upper = [p for p in pts if p.imag > 0.0]
        pts = [min(upper, key=lambda u: abs(u - p.conjugate())).conjugate() if p.imag < 0.0
               else p for p in pts]
    return pts


class ContourWalk:
    """The walk of :func:`count_unstable` along the box: the determinants it holds (read back
    from the checkpoint, or evaluated here or on the executor's workers) and the refinement of
    the contour until every pair of neighbours passes the criteria (module notes)."""

    def __init__(self, op, box, max_step, per_side, max_evals, derivative, phase_rule,
                 checkpoint, checkpoint_every, progress):
        self.op, self.max_step, self.per_side, self.max_evals = op, max_step, per_side, max_evals
        self.x0, self.x1, self.y1 = box
        self.phase_rule, self.progress = phase_rule, progress
        self.checkpoint, self.checkpoint_every = checkpoint, checkpoint_every
        self.key = operator_key(op) if checkpoint else ""
        self.cache, self.note = read_checkpoint(checkpoint, self.key)
        self.checked = bool(derivative)
        # M(σ̄) = conj M(σ) for an operator with real coefficients: one determinant for σ and σ̄
        self.mirror = bool(getattr(op, "conjugate_symmetric", False))
        self.used = set()           # the determinants of this walk (Im σ ≥ 0 only if mirror)
        self.fetched = set()        # points evaluated this run by the workers
        self.resumed = 0
        self.unsaved, self.saved_at = 0, time.perf_counter()
        self.shown = 0              # the largest count passed to progress

    # ---- the determinants
    def report(self, n):
        if self.progress and n > self.shown:
            self.shown = n
            self.progress(n)

    def canon(self, z):
        return z.conjugate() if self.mirror and z.imag < 0.0 else z

    def known(self, z):
        """Whether the cache holds z with all the walk needs (g too, when checked)."""
        hit = self.cache.get(z)
        return hit is not None and (hit[1] is not None or not self.checked)

    def save(self, force=False):
        if self.checkpoint and self.unsaved and (
                force or time.perf_counter() - self.saved_at >= self.checkpoint_every):
            write_checkpoint(self.checkpoint, self.key, self.cache)
            self.unsaved, self.saved_at = 0, time.perf_counter()

    def value(self, z):
        """(arg det M, d ln det M/dz or None, ln|det M|) at z (units of c_p/L), evaluated here
        or read back."""
        if self.known(z):
            self.resumed += z not in self.used and z not in self.fetched
        else:
            M, dM = self.op.matrices(z * self.op.rate_unit, deriv=self.checked)
            if self.checked and dM is None:
                self.checked = False
            if self.checked:
                a, g, la = log_det_derivative(M, dM, with_abs=True)
                self.cache[z] = (a, g * self.op.rate_unit, la)
            else:
                la, a = arg_det(M)
                self.cache[z] = (a, None, la)
            self.unsaved += 1
            self.save()
        if z not in self.used:
            self.used.add(z)
            self.report(len(self.used))
        return self.cache[z]

    def prefetch(self, zs, pool, op_handle):
        """Evaluate the points of `zs` missing from the cache at once, on the pool's workers."""
        if pool is None or not self.checked:
            return
        todo = [z for z in dict.fromkeys(self.canon(z) for z in zs)
                if z not in self.used and not self.known(z)]
        if len(todo) < 2:
            return
        handles = {pool.submit(det_values, op_handle, z): z for z in todo}
        for k, (h, val, err) in enumerate(pool.completed(), 1):
            if err is not None:
                raise err
            z = handles[h]
            self.cache[z] = val
            self.fetched.add(z)
            self.unsaved += 1
            self.report(len(self.used) + k)
            self.save()

    def arg_at(self, z):
        zc = self.canon(z)
        a, g, la = self.value(zc)
        if zc == z:
            return a, g, la
        return -a, (None if g is None else g.conjugate()), la

    # ---- the walk
    def gaps(self, pts, vals):
        """(change of arg det, criterion) per pair of neighbours: the change is the wrapped
        difference on the branch nearest Im T (trapezoid of g) under the 'trapezoid' rule, and
        the criterion max(|g_b − g_a| |Δσ|, |change − Im T|, |Δ ln|det| − Re T|) (0 unchecked)."""
        w = np.array([_wrap(b[0] - a[0]) for a, b in zip(vals, vals[1:])])
        if not self.checked:
            return w, np.zeros(w.size)
        d = w.copy()
        r = np.empty(w.size)
        for k, (a, b, za, zb) in enumerate(zip(vals, vals[1:], pts, pts[1:])):
            trap = 0.5 * (a[1] + b[1]) * (zb - za)
            if self.phase_rule == "trapezoid":
                d[k] = w[k] + 2.0 * math.pi * round((trap.imag - w[k]) / (2.0 * math.pi))
            r[k] = max(abs(b[1] - a[1]) * abs(zb - za), abs(d[k] - trap.imag),
                       abs((b[2] - a[2]) - trap.real))
        return d, r

    def failure(self, steps, gap, bound):
        return ((f"the trapezoid of d ln det M/dsigma still misses the change between "
                 f"neighbours by up to {gap.max():.2f} (criterion {self.max_step})"
                 if self.checked and not bound else
                 f"arg det M still changes by {steps.max():.2f} rad between neighbours"
                 + (f" (derivative criterion {gap.max():.2f})" if self.checked else ""))
                + f" after {len(self.used)} evaluations (budget {self.max_evals})")

    def walk(self, pool=None, op_handle=None):
        """(points, values, changes, criteria, status, message) of the refined contour."""
        pts = _rectangle(self.x0, self.x1, self.y1, self.per_side, symmetric=self.mirror)
        self.arg_at(pts[0])                  # settles `checked` before any batch
        self.prefetch(pts, pool, op_handle)
        vals = [self.arg_at(z) for z in pts]
        while True:            # leaves with the changes and criteria of the final points
            dargs, gap = self.gaps(pts, vals)
            steps = np.abs(dargs)
            bound = not self.checked or self.phase_rule == "wrapped"
            bad = [k for k in range(len(steps))
                   if (bound and steps[k] > self.max_step) or gap[k] > self.max_step]
            if not bad:
                return pts, vals, dargs, gap, "converged", ""
            need = {self.canon(0.5 * (pts[k] + pts[k + 1])) for k in bad} - self.used
            if len(self.used) + len(need) > self.max_evals:
                return pts, vals, dargs, gap, "failed", self.failure(steps, gap, bound)
            self.prefetch(need, pool, op_handle)
            for k in reversed(bad):
                zm = 0.5 * (pts[k] + pts[k + 1])
                pts.insert(k + 1, zm)
                vals.insert(k + 1, self.arg_at(zm))


def count_unstable(op, box=None, max_step=0.6, per_side=6, max_evals=400, integer_tol=0.05,
                   progress=None, derivative=True, checkpoint=None, checkpoint_every=60.0,
                   phase_rule="trapezoid", executor=None):
    """Count the eigenvalues of M(σ) in the box x0 ≤ Re σ L/c ≤ x1, |Im σ L/c| ≤ y1.

    Parameters
    ----------
    op : StabilityOperator
    box : (x0, x1, y1) in units of c_p/L; x0 > 0 (the analytic half-plane).
    max_step : largest accepted change of arg det M between neighbouring points, rad.
    per_side : starting points per side of the rectangle.
    max_evals : budget of determinant evaluations (one LU of an N×N complex matrix each), new or
        read back. An operator with ``conjugate_symmetric`` true (real coefficients:
        M(σ̄) = conj M(σ), as the pulse operators) is evaluated on Im σ ≥ 0 only; the lower half
        of the box follows by conjugation.
    integer_tol : largest accepted distance of the winding number from an integer.
    progress : callable(n_evals) or None.
    derivative : use g = d ln det M/dσ (module notes; one more solve with N right-hand sides per
        evaluation). False: the wrapped change alone.
    phase_rule : 'trapezoid' (default): the branch of each change from the trapezoid of g, no
        bound on the change itself; 'wrapped': also bounds the wrapped change by `max_step`
        (the older, costlier rule, for comparisons).
    checkpoint : path of a file that keeps the evaluations (module notes), or None. Read at the
        start if it was written for this operator, rewritten at most every `checkpoint_every`
        seconds and at the end of the walk. Left in place: the caller removes it when done.
    executor : :class:`slippulse.core.executor.ExecutorSettings` or None. Parallel (several
        workers or a scheduler) and with the derivative, the points of each round of the walk
        (the starting rectangle, then the midpoints of every pair that fails the criteria) are
        evaluated at once on the workers, the operator sent to each once; the walk visits the
        same points and ends as serially, in about (evaluations / workers + rounds)
        evaluation times.
    """
    from ..core.executor import ExecutorSettings, TaskPool
    t0 = time.perf_counter()
    if phase_rule not in ("trapezoid", "wrapped"):
        raise ValueError(f"phase_rule={phase_rule!r}: 'trapezoid' or 'wrapped'")
    x0, x1, y1 = (float(b) for b in box)
    if not (0.0 < x0 < x1 and y1 > 0.0):
        raise ValueError(f"box={box!r}: need 0 < x0 < x1 and y1 > 0 (units of c_p/L)")
    executor = executor if executor is not None else ExecutorSettings()
    w = ContourWalk(op, (x0, x1, y1), max_step, per_side, max_evals, derivative, phase_rule,
                    checkpoint, checkpoint_every, progress)
    if executor.parallel and derivative:
        with TaskPool(executor) as pool:
            walked = w.walk(pool, pool.scatter(op))
    else:
        walked = w.walk()
    w.save(force=True)
    return _result(w, *walked, integer_tol, time.perf_counter() - t0)


def _result(w, pts, vals, dargs, gap, status, msg, integer_tol, wall):
    """The :class:`ContourCount` of a finished walk: the winding number, an integer or not."""
    unwrapped = np.concatenate([[vals[0][0]], vals[0][0] + np.cumsum(dargs)])
    winding = float(np.sum(dargs) / (2.0 * math.pi))
    count = None
    if status == "converged":
        if abs(winding - round(winding)) > integer_tol:
            status = "failed"
            msg = f"winding number {winding:.3f} is not an integer within {integer_tol}"
        else:
            count = int(round(winding))
            msg = (f"{count} eigenvalue(s) in {w.x0:g} <= Re sigma L/c <= {w.x1:g}, "
                   f"|Im sigma L/c| <= {w.y1:g}")
    return ContourCount(count, winding, (w.x0, w.x1, w.y1), len(w.used),
                        float(np.max(np.abs(dargs))) if dargs.size else 0.0, status, msg,
                        wall, np.array(pts), unwrapped,
                        float(gap.max()) if w.checked and gap.size else float("nan"),
                        w.resumed, w.note, np.array([v[2] for v in vals], float),
                        np.array([v[1] for v in vals], complex) if w.checked else None)


#: Largest count whose zeros :func:`zeros_in_box` estimates: beyond it the Hankel matrices of the
#: moments lose the separation of the zeros to the quadrature's error.
MAX_LOCATE = 8


def zeros_in_box(cnt: ContourCount, known=()) -> np.ndarray:
    """Estimates of the zeros of det M inside a converged count's box (σ L/c_p), from the walk's
    own evaluations (the moments of Delves and Lyness): s_p = (1/2πi)∮ z^p g dz = Σ_k z_k^p with
    z = (σ − c)/r (c the box's centre, r its half-width) are the power sums of the C zeros, and
    the zeros are the eigenvalues of the pencil (H₁, H₀), H_m[i, j] = s_{i+j+m}. ``known``
    (σ L/c_p, inside the box): zeros already found; their powers are taken off the sums and
    only the C − K others are estimated, a smaller and better conditioned pencil.

    On each segment g is taken as the quadratic in the arclength that matches g at both ends
    and the exact change of ln det M between them (ln|det| and the branch-resolved arg, the
    count's own), and z^p times it is integrated exactly. Why: g holds a large smooth part
    (module notes) that integrates to nothing around the box but swamps the zeros' part under a
    trapezoid on the walk's long segments far from any zero. Why locate at all: the
    eigen-search from a neighbour's eigenvalue finds *an* eigenvalue, not the leading one
    (two-hump pulse at 1.2 τ_min: 1.38 or 14.98 for 44.54 c_p/L); these estimates, polished by
    Newton, find what it missed. Empty where the count failed, the others number 0 or more than
    :data:`MAX_LOCATE`, or the walk was made without M′."""
    C = cnt.count
    x0, x1, y1 = cnt.box
    known = [complex(k) for k in known
             if x0 <= k.real <= x1 and abs(k.imag) <= y1]
    m = (C or 0) - len(known)
    if m <= 0 or m > MAX_LOCATE or cnt.g is None or cnt.points.size < 2:
        return np.zeros(0, complex)
    c, r = complex(0.5 * (x0 + x1), 0.0), max(0.5 * (x1 - x0), y1)
    s = _power_sums(cnt, c, r, 2 * m)
    for k in known:
        s -= ((k - c) / r) ** np.arange(2 * m)
    H0, H1 = hankel(s[:m], s[m - 1:2 * m - 1]), hankel(s[1:m + 1], s[m:2 * m])
    try:
        w = eigvals(H1, H0)
    except (np.linalg.LinAlgError, ValueError):
        return np.zeros(0, complex)
    w = w[np.isfinite(w)]
    return np.sort_complex(c + r * w)


def _power_sums(cnt: ContourCount, c, r, n) -> np.ndarray:
    """(1/2πi)∮ z^p g dz for p < n, z = (σ − c)/r, by the quadratic model of :func:`zeros_in_box`."""
    z = (np.asarray(cnt.points, complex) - c) / r
    g = np.asarray(cnt.g, complex) * r                        # d ln det/dz
    dl = np.diff(cnt.log_abs) + 1j * np.diff(cnt.args)        # exact change of ln det M
    zm, h = 0.5 * (z[1:] + z[:-1]), np.diff(z)
    beta = np.diff(g)                                         # g = α + β t + γ t², |t| ≤ ½
    gamma = 6.0 * (0.5 * (g[1:] + g[:-1]) - dl / h)
    alpha = dl / h - gamma / 12.0
    T = [0.0 if k % 2 else 2.0 * 0.5 ** (k + 1) / (k + 1) for k in range(n + 3)]  # ∫ t^k dt
    s = np.empty(n, complex)
    for p in range(n):
        seg = np.zeros(zm.size, complex)
        for j in range(p + 1):
            seg += (math.comb(p, j) * zm ** (p - j) * h ** j
                    * (alpha * T[j] + beta * T[j + 1] + gamma * T[j + 2]))
        s[p] = np.sum(h * seg) / (2j * math.pi)
    return s
