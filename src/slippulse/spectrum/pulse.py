"""Linear stability spectrum of steady pulses on the steady solver's grid (docs/spectrum.md): the
per-pulse driver (:func:`pulse_spectrum`) and its result (:class:`PulseSpectrum`).

The linearised problem M(σ) V₁ = 0 and its derivation are stated in :mod:`.operators` (and
docs/spectrum.md §1–2). Eigenvalues are found by shift-invert Arnoldi on the linearisation
M(σ_a) + (σ − σ_a) M′(σ_a) and refined by Newton on the bordered system (nonlinear inverse
iteration with the exact M′).

The operators live in :mod:`.operators`, the eigen-solvers in :mod:`.eigensolve`, the storage in
:mod:`.store`; they are re-exported here.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..core.h5io import UNSTORED_STATE_ORDER, state_order_of
from .eigensolve import (PURIFY_SOLVES, Eigen, det_sign, linearised_candidates, neutral_modes,
                         newton_eigen, real_eigenvalues)
from .operators import ElasticOperator, StabilityOperator, slope_matrix, symbol
from .store import MODE_FIELDS, SPECTRUM_GROUP, read_spectrum, write_spectrum

__all__ = ["DEFAULT_SHIFTS", "MIN_RE", "MODE_FIELDS", "NEWTON_TOL", "SPECTRUM_GROUP", "TRACK_FLOOR", "Eigen",
           "ElasticOperator", "PulseSpectrum", "StabilityOperator", "linearised_candidates", "neutral_modes",
           "newton_eigen", "order4_pulse", "pulse_spectrum", "read_spectrum", "slope_matrix",
           "symbol", "write_spectrum"]


DEFAULT_SHIFTS = (25.0, 8.0, 2.0, 0.5, 0.15, 0.05)   # first search shifts, in units of c_p/L
MIN_RE = 1e-3                              # eigenvalues with Re σ < MIN_RE c/L are not sought
TRACK_FLOOR = 0.1                          # ... except a tracked one, down to this × its guess
NEWTON_TOL = 1e-6                          # Newton's step criterion (pulse_spectrum's tol)
#: Below MIN_RE c/L, with translation pinned and nothing tracked or found above: the real axis
#: [SCAN_LO, MIN_RE] c/L is scanned for a sign change of det M(σ) at SCAN_POINTS geometric points
#: (two per decade), and an eigenvalue it brackets is refined by Arnoldi and Newton. A deep pulse
#: analysed on its own (no neighbour above, no --guess) is found so, instead of reading as
#: "no eigenvalue" (its s L/c_p is 7e-5 to 3e-4 at L = 0.4-6.7 km). Unpinned, the translation
#: mode lies in that range too (its discretisation error), so no scan is made.
SCAN_LO = 1e-7
SCAN_POINTS = 9


@dataclass
class PulseSpectrum:
    """Eigenvalues of one pulse (sorted by decreasing Re σ), their modes, the neutral pair."""

    label: str
    sigmas: np.ndarray            # complex, 1/s
    modes: list                   # dicts of fields per eigenvalue (see StabilityOperator.fields)
    neutral: np.ndarray           # σ of uniform slip and translation (1/s)
    translation_error: float      # relative distance of the translation mode from δ₀′ (in V₁)
    rate_unit: float              # c_p / L, 1/s
    n_points: int
    status: str
    message: str
    wall_time: float
    newton_iterations: int = 0
    failures: list = field(default_factory=list)
    stage_times: dict = field(default_factory=dict)
    refined: object = None        # RefinedRate of the leading eigenvalue (spectrum.refine)
    count: object = None          # ContourCount (spectrum.count), if asked for
    operator: object = field(default=None, repr=False)   # the StabilityOperator (not stored)
    xi: object = None             # the grid of the modes (the pulse's, or a nested refinement)
    level0_attempt: str = ""      # how level 0 was built (spectrum.family.LEVEL0_ATTEMPTS)
    leading_from: str = "search"  # "search", or "count" where the count's zeros found a larger one

    @property
    def n_unstable(self):
        return int(np.sum(self.sigmas.real > 0))

    @property
    def leading(self):
        return complex(self.sigmas[0]) if self.sigmas.size else complex("nan")


def translation_check(op, sigs, vecs):
    """Pick the translation mode among the near-zero pencil modes: the one whose V₁ is closest
    to v₀′ (δ₁ = δ₀′ ⇒ V₁ = −c δ₀″ = v₀′). Returns (σ_t, relative distance, index)."""
    vp = op.S @ op.v0                                   # v₀′ on the grid (spline slopes)
    best = (complex("nan"), np.inf, -1)
    for j in range(len(sigs)):
        V = vecs[:, j]
        nv = np.linalg.norm(V)
        if nv == 0.0:
            continue
        a = np.vdot(vp, V) / np.vdot(vp, vp)
        d = float(np.linalg.norm(V - a * vp) / np.linalg.norm(a * vp))
        if d < best[1]:
            best = (complex(sigs[j]), d, j)
    return best


def order4_pulse(pulse, params):
    """The pulse itself if it was solved with the order-4 state integrator; otherwise (files
    written with ``state_order`` 2) re-solved at order 4 on its own grid from its own ln v
    and β. Raises UsageError if that re-solve does not converge."""
    try:
        order = state_order_of(pulse)
    except (TypeError, ValueError):
        order = UNSTORED_STATE_ORDER
    if order == 4:
        return pulse
    from ..core.errors import UsageError
    from ..steady.solver import SolveOptions, SteadySolution, solve_on_grid
    t0 = time.perf_counter()
    v = np.asarray(pulse.v, float)
    if not (np.all(np.isfinite(v)) and np.all(v > 0) and np.all(np.isfinite(pulse.xi))):
        raise UsageError(f"pulse {pulse.label}: non-finite or non-positive slip rates or grid; "
                         "it cannot be re-solved at state order 4")
    try:
        prob, x, stats = solve_on_grid(params, pulse.tau_d_ratio, np.asarray(pulse.xi, float),
                                       np.log(v), pulse.beta, SolveOptions(state_order=4))
    except (RuntimeError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        raise UsageError(f"pulse {pulse.label} was solved with state order 2 and could not be "
                         f"re-solved at order 4 on its grid ({exc})") from None
    if not stats.converged:
        raise UsageError(f"pulse {pulse.label} was solved with state order 2 and could not be "
                         f"re-solved at order 4 on its grid ({stats.message}): re-solve it with "
                         "the current `slippulse steady solve`/`family`")
    return SteadySolution(prob, x, stats, time.perf_counter() - t0, 0).to_pulse()


def _scan_brackets(op):
    """Intervals (lo, hi) in 1/s where det M(σ) changes sign, on a geometric scan of
    [SCAN_LO, MIN_RE] c/L walked from the top down (the largest real eigenvalue first); a
    generator, so that the walk stops where an eigenvalue is found (4 evaluations at s L/c_p ~
    1e-4)."""
    pts = np.geomspace(MIN_RE, SCAN_LO, SCAN_POINTS) * op.rate_unit
    prev = det_sign(op, pts[0])[0]
    for hi, lo in zip(pts, pts[1:]):
        sign = det_sign(op, lo)[0]
        if sign * prev < 0:
            yield lo, hi
        prev = sign


def scan_below(op, add):
    """The leading real eigenvalue below MIN_RE c/L (see :data:`SCAN_LO`): for each bracket of
    :func:`_scan_brackets`, from the top, the linearised candidates at its geometric middle (then,
    if Newton loses them, at Brent's root of det M in it) are handed to
    ``add(sigma, vector, floor=...)``, until add returns True (an eigenvalue found)."""
    unit = op.rate_unit
    for lo, hi in _scan_brackets(op):
        for sa in (np.sqrt(lo * hi), None):
            if sa is None:
                roots = real_eigenvalues(op, lo, hi, n_scan=2, xtol=1e-6).roots
                if not roots:
                    break
                sa = roots[0]
            sig, vec = linearised_candidates(op, complex(sa), k=2)
            if any([add(complex(sig[j]), vec[:, j], floor=0.5 * lo / unit)
                    for j in range(len(sig))]):
                return


def pulse_spectrum(pulse, params, guesses=(), extra=True, tol=NEWTON_TOL, label="",
                   guess_modes=None, pin_translation=False, neutral=True):
    """Leading eigenvalues and modes of one pulse.

    guesses : σ values (1/s) to start from (e.g. the neighbouring pulse's eigenvalues, rescaled);
        the shifts DEFAULT_SHIFTS·c/L are tried after them (or alone) until an eigenvalue is found;
        then, pinned, the real axis below MIN_RE c/L by the sign of det M (:func:`scan_below`).
    extra : after the leading eigenvalue, search below it (shift at 0.4 Re σ₁, 2 candidates),
        for eigenvalues with Re σ > MIN_RE c/L: not made where Re σ₁ is below that.
    tol : Newton's step criterion, relative to max(|σ|, c/L); the iteration converges
        quadratically, so the σ returned (after that step) is accurate to ~tol² (measured on a
        refinement level at 1.05 τ_min, N = 1414, from the level below: steps 7e-4, 4.6e-7,
        1e-13; with tol = 1e-6 the iteration stops after the second).
    guess_modes : V₁ on this pulse's grid for each guess (e.g. the neighbour's mode moved over in
        ξ/L); Newton starts from (guess, mode) directly and the Arnoldi stage is skipped when it
        converges.
    pin_translation : solve the problem with translation pinned (:class:`StabilityOperator`'s
        rank-one change that makes v₀′ an exact null vector of M(0); σ_t is then 0 by
        construction, not a check; docs/spectrum.md §2).
    neutral : also compute the neutral pair (translation σ_t and the uniform-slip backward error;
        two more assemblies at σ = 0, an Arnoldi and a dense product). Pinned, σ_t = 0 by
        construction and is stored as nan (not computed); the uniform-slip error is computed.
        False stores nan for both: the refinement levels of a pinned ladder
        (:func:`slippulse.spectrum.refine.refine_leading`).
    """
    t0 = time.perf_counter()
    op = StabilityOperator(order4_pulse(pulse, params), params, pin_translation)
    search = EigenSearch(op, tol)
    scanned = search.leading(guesses, guess_modes, pin_translation)
    t1 = time.perf_counter()
    if extra:
        search.below_leading()
    found = search.with_conjugates()
    t2 = time.perf_counter()
    neutral_pair, terr = neutral_pair_of(op, pin_translation) if neutral else \
        (np.full(2, np.nan, complex), float("nan"))
    modes = [op.fields(f.sigma, f.V) for f in found]
    status, msg = _outcome(found, search.failures, scanned)
    t3 = time.perf_counter()
    return PulseSpectrum(label or pulse.label, np.array([f.sigma for f in found], complex), modes,
                         neutral_pair, terr, op.rate_unit, op.n, status, msg, t3 - t0,
                         search.iterations, search.failures,
                         {"leading": t1 - t0, "extra": t2 - t1, "neutral": t3 - t2},
                         operator=op, xi=op.xi)


class EigenSearch:
    """The eigenvalues found so far on one operator, and the stages that look for more: Newton
    from tracked starts, Arnoldi at tracked and default shifts, the scan below MIN_RE, the
    search below the leading one. Each candidate is refined by Newton and kept if it converges
    above its floor and is new."""

    def __init__(self, op, tol):
        self.op, self.tol, self.unit = op, tol, op.rate_unit
        self.found, self.failures, self.iterations = [], [], 0

    def add(self, cand_sig, cand_vec, max_iter=12, floor=MIN_RE, purify=0):
        """Newton from (σ, V); True if it found a new eigenvalue above `floor` c/L."""
        unit = self.unit
        if not cand_sig.real > floor * unit:
            return
        if any(abs(cand_sig - f.sigma) < 1e-3 * max(abs(f.sigma), unit) for f in self.found):
            return
        eig = newton_eigen(self.op, cand_sig, cand_vec, tol=self.tol, min_re=floor * unit,
                           max_iter=max_iter, purify=purify)
        self.iterations += eig.iterations
        if not eig.converged:
            self.failures.append(f"from {cand_sig / unit:.4g} c/L: {eig.message}")
            return
        if eig.sigma.real > floor * unit and not any(
                abs(eig.sigma - f.sigma) < 1e-6 * max(abs(f.sigma), unit) for f in self.found):
            self.found.append(eig)
            return True
        return False

    def leading(self, guesses, guess_modes, pin_translation):
        """The leading eigenvalue: from the tracked (guess, mode) pairs by Newton; then Arnoldi
        at the tracked shifts (their candidates followed down to a tenth of the guess, the two
        nearest: near τ_min the translation mode is the other one), then at the default shifts;
        pinned and still nothing, the real axis below MIN_RE by the sign of det M. Returns
        whether that scan was made."""
        unit = self.unit
        tracked = [complex(g) for g in guesses]
        if guess_modes is not None:
            # a tracked eigenvalue is followed below MIN_RE c/L (deep pulses: s L/c_p ≪ 1e-3),
            # down to a tenth of its guess, which keeps Newton off the translation mode at 0
            for g, v in zip(tracked, guess_modes):
                floor = min(MIN_RE, TRACK_FLOOR * g.real / unit)
                if v is not None and floor > 0:      # a mode from elsewhere: purified first
                    self.add(g, np.asarray(v, complex), floor=floor, purify=PURIFY_SOLVES)
        n_tracked = len(tracked)
        for i, sa in enumerate(tracked + [complex(q * unit) for q in DEFAULT_SHIFTS]):
            if self.found:
                break
            floor = min(MIN_RE, TRACK_FLOOR * sa.real / unit) if i < n_tracked else MIN_RE
            if not (floor > 0 and sa.real > floor * unit):
                continue
            sig, vec = linearised_candidates(self.op, sa, k=2 if i < n_tracked else 1)
            for j in range(len(sig)):
                self.add(complex(sig[j]), vec[:, j], floor=floor)
        scanned = not self.found and pin_translation
        if scanned:
            scan_below(self.op, self.add)
        return scanned

    def below_leading(self):
        """A search below the leading eigenvalue (shift at 0.4 Re σ₁, two candidates). Not
        where the leading rate is below MIN_RE c/L, as on the deep pulses: an eigenvalue below
        it would be below the floor that add() keeps, and the search costs an assembly, a
        factorisation and an Arnoldi (3 s at N = 3542)."""
        lead = max((f.sigma.real for f in self.found), default=0.0)
        if self.found and lead > MIN_RE * self.unit:
            sig, vec = linearised_candidates(self.op, 0.4 * lead, k=2)
            for j in range(len(sig)):
                self.add(complex(sig[j]), vec[:, j], max_iter=8)

    def with_conjugates(self):
        """The eigenvalues found, each complex one with its partner (M(σ̄) = conj M(σ)), by
        decreasing Re σ."""
        found = self.found
        for f in list(found):
            if abs(f.sigma.imag) > 1e-8 * abs(f.sigma) and not any(
                    abs(g.sigma - f.sigma.conjugate()) < 1e-6 * abs(f.sigma) for g in found):
                found.append(Eigen(f.sigma.conjugate(), f.V.conj(), True, 0, f.residual,
                                   "conjugate"))
        found.sort(key=lambda f: -f.sigma.real)
        return found


def polish_located(op, cnt, known=(), tol=NEWTON_TOL):
    """The eigenvalues (1/s, by decreasing Re σ) inside a converged count's box: ``known`` (1/s,
    e.g. the search's) and those polished by Newton from the count's own zero estimates
    (:func:`~.count.zeros_in_box`: one linearised Arnoldi at each estimate inside the box
    widened by a tenth), estimated again with the ones found taken off while that finds more.
    Returns (those eigenvalues, {σ: V} of the polished ones) and stores the eigenvalues on the
    count as ``located`` (c_p/L). Why: where their number equals the count, the eigenvalues in
    the box are all known, the leading one among them, whatever the search started from."""
    from .count import zeros_in_box
    x0, x1, y1 = cnt.box
    unit = op.rate_unit
    pad = 0.1 * max(x1 - x0, y1)

    def inside(z, p=0.0):
        return x0 - p <= z.real <= x1 + p and abs(z.imag) <= y1 + p

    found = [complex(k) for k in known if inside(complex(k) / unit)]
    search = EigenSearch(op, tol)
    while len(found) < (cnt.count or 0):
        before = len(search.found)
        for z in sorted(zeros_in_box(cnt, [f / unit for f in found]), key=lambda z: -z.real):
            if inside(z, pad):          # the shift inside the box: M needs Re σ > 0
                shift = complex(min(max(z.real, x0), x1), min(abs(z.imag), y1))
                sig, vec = linearised_candidates(op, shift * unit, k=1)
                for j in range(len(sig)):
                    search.add(complex(sig[j]), vec[:, j], floor=x0)
        if len(search.found) == before:
            break
        new = [f.sigma for f in search.with_conjugates() if inside(f.sigma / unit)]
        found += [s for s in new if all(abs(s - k) > 1e-6 * abs(s) for k in found)]
    found.sort(key=lambda s: -s.real)
    cnt.located = np.array(found, complex) / unit
    return np.array(found, complex), {f.sigma: f.V for f in search.found}


def neutral_pair_of(op, pin_translation):
    """([uniform-slip backward error, σ_t], translation mode error) of the neutral pair.
    Pinned, σ_t = 0 by construction (the pin makes v₀′ an exact null vector of M(0)): the
    Arnoldi at σ = 0 that finds it unpinned would only return rounding (≤ 1e-13 c/L), at the
    cost of an assembly with M′ and a factorisation (6 s of a deep pulse's 50 s at N = 3542);
    nan says "not computed"."""
    if pin_translation:
        sig_t, terr = complex("nan"), float("nan")
    else:
        nsig, nvec = neutral_modes(op)
        sig_t, terr, _ = translation_check(op, nsig, nvec)
    # uniform slip (δ₁ = 1, V₁ = 0) is outside the V₁ form; in the δ₁ form it is exact at σ = 0
    Md = op.matrices_delta(0.0)
    one = np.ones(op.n)
    uniform = float(np.max(np.abs(Md @ one) / (np.abs(Md) @ one)))   # backward error
    return np.array([uniform, sig_t]), terr


def _outcome(found, failures, scanned):
    """(status, message) of a pulse's search."""
    if found:
        return "converged", f"{len(found)} eigenvalue(s) with Re sigma > {MIN_RE:g} c/L"
    if failures:
        return "failed", "; ".join(failures[:3])
    if scanned:
        return "converged", (f"no eigenvalue with Re sigma > {MIN_RE:g} c/L found, and no sign "
                             f"change of det M on [{SCAN_LO:g}, {MIN_RE:g}] c/L")
    return "converged", f"no eigenvalue with Re sigma > {MIN_RE:g} c/L found"
