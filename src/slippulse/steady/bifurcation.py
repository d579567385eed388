"""Test functions for folds and branch points of a one-parameter family, and their locator.

A *system* is any object with ``residual_and_jacobian(x) -> (r, J)``: n equations in n + 1
unknowns x = (u, λ), the parameter λ last, J of shape n × (n + 1). For the steady pulse that is
:class:`~slippulse.steady.equations.SteadyProblem` with ``free="both"``: u = (ln v, β), λ = q =
τ_d/τ_min, the phase condition (the front pin) the last row (:func:`pulse_system`). Then

* A = J[:, :n] is the pinned fixed-τ_d Newton matrix [F_u F_c]: singular at a fold in λ and at a
  branch point (docs/branches.md §1);
* t, the unit null vector of J, is the family's tangent, unique where J has full rank n;
* B = [J; t^T] is the bordered matrix of pseudo-arclength continuation: regular at a fold,
  singular at a branch point (J rank n − 1).

Cramer's rule gives det A = det B · t_λ exactly (:func:`indicators` returns both for a check).
Hence, along a branch with t oriented by continuity, a fold is a sign change of t_λ (of det A, with
det B of one sign), and a simple branch point a sign change of det B (of both det B and t_λ, det A
keeping its sign or not). The signs of two determinants are comparable only on one discretisation
(the same N and a grid deformed continuously); :func:`scan` says where they are not, and the
smallest singular values σ₁ ≤ σ₂ of B (a branch point drives σ₁ → 0, a fold does not) are the
grid-independent indicator.

:func:`locate` finds the zero between two solutions of one system by regula falsi (Illinois) on
a test function along the branch, parametrised by the chord hyperplane
d·(x − x_a) = θ|d|², d = x_b − x_a (which passes folds and branch points alike):
ψ(θ) = det[J; d^T] (zero only at a branch point) or φ(θ) = det A (zero at a fold).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from .singular import DENSE_SVD_MAX, smallest_singular_values  # noqa: F401 (re-exported)


def lu_det(M):
    """(sign, ln|det M|) from an LU factorisation: the product of U's diagonal signs and the
    permutation's parity. Returns (sign, logdet, lu); sign 0 for an exactly singular M."""
    lu, piv = sla.lu_factor(M, check_finite=False)
    sign = lu_sign((lu, piv))
    if sign == 0:
        return 0, -math.inf, (lu, piv)
    return sign, float(np.sum(np.log(np.abs(np.diag(lu))))), (lu, piv)


def lu_sign(lu) -> int:
    """The sign of det of the matrix whose scipy LU is ``lu``: the product of U's diagonal signs
    and the pivots' parity (0 for an exactly singular U)."""
    d = np.diag(lu[0])
    if np.any(d == 0):
        return 0
    parity = int(np.count_nonzero(lu[1] != np.arange(lu[1].size))) % 2
    return int((-1) ** parity * np.prod(np.sign(d)))


#: Above this many equations the null vector comes from one bordered LU solve instead of a full
#: QR (a third of the work; 6615 equations: one LU of ~40 s on this machine instead of a QR of ~2 min).
QR_MAX = 2000


def null_vector(J):
    """Unit null vector of an n × (n + 1) matrix of rank n: the last column of Q in J^T = QR; for
    n > :data:`QR_MAX`, the solution of [J; e_kᵀ] t = e_{n+1} normalised, k the column whose
    removal leaves J best conditioned among the last two (the pulse's β and q), refined once."""
    n = J.shape[0]
    if n <= QR_MAX:
        Q, _ = sla.qr(J.T, mode="full", check_finite=False)
        return Q[:, -1].copy()
    best = None
    for k in (n, n - 1):
        M = np.vstack([J, np.eye(1, n + 1, k)])
        lu = sla.lu_factor(M, check_finite=False)
        rhs = np.zeros(n + 1)
        rhs[-1] = 1.0
        t = sla.lu_solve(lu, rhs, check_finite=False)
        t /= np.linalg.norm(t)
        # one refinement step against the residual J t
        t -= sla.lu_solve(lu, np.concatenate([J @ t, [0.0]]), check_finite=False)
        t /= np.linalg.norm(t)
        res = float(np.linalg.norm(J @ t))
        if best is None or res < best[0]:
            best = (res, t)
        if abs(t[k]) > 0.1 * float(np.max(np.abs(t))):
            break
    return best[1]


def null_vector_from_lu(J, lu):
    """Unit null vector of an n × (n + 1) matrix J = [A c] from the LU of A (scipy
    ``lu_factor``), A regular: t ∝ (−A⁻¹c, 1), refined once against the residual J t; None when
    it is not finite or its residual ‖J t‖ exceeds 1e-10 ‖J‖ (then take :func:`null_vector`).

    The fold test factors A anyway (:func:`indicators`), so the tangent costs two
    back-substitutions instead of a QR of Jᵀ (with Q formed: about three LUs of A). Near a fold
    A⁻¹c grows like 1/t_λ, but its error lies along the same near-null direction, which the
    normalisation removes (the argument of inverse iteration): the same t to round-off, measured
    against the QR on the shallow family (tests/test_bifurcation.py).
    """
    n = J.shape[0]
    u = -sla.lu_solve(lu, J[:, n], check_finite=False)
    u -= sla.lu_solve(lu, J[:, :n] @ u + J[:, n], check_finite=False)
    t = np.concatenate([u, [1.0]])
    t /= np.linalg.norm(t)
    if not np.all(np.isfinite(t)):
        return None
    if np.linalg.norm(J @ t) > 1e-10 * np.linalg.norm(J, ord=np.inf):
        return None
    return t


@dataclass
class Indicators:
    """Test functions at one solution (J column-scaled by ``scale``; signs need no scale).

    fold_sign, fold_logdet : sign and ln|det| of A = J[:, :n] (the fixed-λ Newton matrix).
    bordered_sign, bordered_logdet : the same of B = [J; t^T].
    tangent : unit null vector t of J, oriented by ``orient`` when given (t·orient > 0).
    t_param : t's λ component (t_λ); det A = det B · t_λ (Cramer).
    sigma : the two smallest singular values of B, ascending.
    n : number of equations.
    lu_a : scipy's LU of A (column-scaled as J), None where A is singular.
    """
    fold_sign: int
    fold_logdet: float
    bordered_sign: int
    bordered_logdet: float
    tangent: np.ndarray = field(repr=False)
    t_param: float
    sigma: tuple
    n: int
    lu_a: tuple | None = field(default=None, repr=False)

    @property
    def cramer_defect(self) -> float:
        """|det A − det B t_λ| / |det A| from the logs (0 when Cramer's identity holds)."""
        if self.fold_sign == 0:
            return math.inf
        rhs = self.bordered_sign * math.copysign(1.0, self.t_param) * math.exp(
            self.bordered_logdet + math.log(abs(self.t_param)) - self.fold_logdet)
        return abs(self.fold_sign - rhs)


#: The test functions of B = [J; tᵀ] come from the LU of A = J[:, :n] (which the fold test
#: factors) where |t_λ| ≥ this: det B = det A / t_λ (Cramer) and B⁻¹, B⁻ᵀ by bordering with
#: A⁻¹; nearer a fold, where A⁻¹ grows like 1/t_λ, B is factored itself. One LU per pulse
#: instead of two; the same sign, ln|det| and σ₁, σ₂ as B's own LU to 2e−12 down to
#: t_λ = 3.7e−8 (BENCHMARKS.md "Deep family"); at t_λ = 1.2e−9 ln|det| differed by 2e−4.
BORDER_MIN = 1e-8


def _bordered_solve(lu_a, J, t):
    """``solve(r, trans)`` = B⁻¹ r or B⁻ᵀ r for B = [J; tᵀ] = [[A, c], [t_Aᵀ, t_λ]], J t = 0,
    |t| = 1, with the LU of A: w = A⁻¹c, t = (−w, 1)/ν, so both Schur complements equal ν."""
    n = J.shape[0]
    c, tA, tl = J[:, n], t[:n], t[n]
    w = sla.lu_solve(lu_a, c, check_finite=False)
    schur = tl - tA @ w                     # of A in B, and in Bᵀ

    def solve(r, trans=0):
        r = np.asarray(r, float)
        if trans == 0:
            a = sla.lu_solve(lu_a, r[:n], check_finite=False)
            zl = (r[n] - tA @ a) / schur
            return np.concatenate([a - w * zl, [zl]])
        zl = (r[n] - w @ r[:n]) / schur
        za = sla.lu_solve(lu_a, r[:n] - tA * zl, trans=1, check_finite=False)
        return np.concatenate([za, [zl]])
    return solve


def indicators(J, scale=None, orient=None, singular_values=True) -> Indicators:
    """Fold and branch-point test functions of a solution with extended Jacobian J (n × (n+1)).

    scale : column scaling (x = scale · x̂; the functions of the scaled unknowns x̂), e.g. β for
        the speed column of a pulse; default none.
    orient : a vector of length n + 1 (in the same scaled unknowns); t is flipped so that
        t·orient > 0 (continuity along a family). Default: the sign QR gives.
    """
    J = np.asarray(J, dtype=float)
    if scale is not None:
        J = J * np.asarray(scale, dtype=float)[None, :]
    n = J.shape[0]
    if J.shape != (n, n + 1):
        raise ValueError(f"extended Jacobian must be n x (n+1), got {J.shape}")
    fs, fl, lu_a = lu_det(J[:, :n])
    t = null_vector_from_lu(J, lu_a) if fs != 0 else None
    if t is None:
        t = null_vector(J)
    if orient is not None and float(np.dot(t, orient)) < 0:
        t = -t
    B = np.vstack([J, t[None, :]])
    if fs != 0 and abs(t[-1]) >= BORDER_MIN:
        bs = fs * (1 if t[-1] > 0 else -1)
        bl = fl - math.log(abs(t[-1]))
        solve = _bordered_solve(lu_a, J, t)
        sig = (tuple(float(s) for s in smallest_singular_values(B, solve=solve))
               if singular_values else ())
    else:
        bs, bl, lu = lu_det(B)
        sig = tuple(float(s) for s in smallest_singular_values(B, lu)) if singular_values else ()
    return Indicators(fs, fl, bs, bl, t, float(t[-1]), sig, n, lu_a if fs != 0 else None)


# --------------------------------------------------------------------------- locating a zero
@dataclass
class Bifurcation:
    """A located fold or branch point: ``kind`` ('fold' or 'branch point'), its unknowns x (the
    parameter last), the chord position θ in [0, 1], the test function's value there relative to
    the bracket's (``residual_test``), the evaluations it took, and whether the bracket closed
    (``converged``; when not, x is only the best point met). ``jump``: the bracket closed on a
    sign change with no zero (:data:`JUMP_TEST`): the chord passes from one solution branch to
    another, and x is no fold or branch point."""
    kind: str
    x: np.ndarray = field(repr=False)
    theta: float
    parameter: float
    residual_test: float
    evaluations: int
    extra: dict = field(default_factory=dict)
    converged: bool = True        # False: max_eval reached with the bracket still open
    jump: bool = False


#: A bracket closed to ``theta_tol`` around a simple zero leaves |test| ≈ |test'| θ_tol, far
#: below this (relative to its value at x_a) unless the zero lies within ~1e-7 of x_a; one that
#: closes with |test| above this has bracketed a jump of the test function's sign, not a zero:
#: the chord's Newton solutions pass from one solution branch to a nearby other one there (seen
#: between two-hump pulses that a march took from both sides of a fold: |test| = 0.11 there).
JUMP_TEST = 1e-3


class LocateError(RuntimeError):
    """The locator could not bracket or converge (message says which)."""


def _newton_on_chord(system, x0, xa, d, theta, tol, max_iter):
    """Solve F(x) = 0, d·(x − x_a) = θ|d|² by Newton from x0; returns (x, J) or raises."""
    dd = float(d @ d)
    x = np.array(x0, dtype=float)
    for _ in range(max_iter):
        r, J = system.residual_and_jacobian(x)
        g = float(d @ (x - xa)) - theta * dd
        if np.max(np.abs(r)) <= tol and abs(g) <= tol * math.sqrt(dd):
            return x, J
        M = np.vstack([J, d[None, :]])
        step = sla.solve(M, -np.concatenate([r, [g]]), check_finite=False)
        x = x + step
        valid = getattr(system, "valid", None)
        if valid is not None and not valid(x):
            raise LocateError(f"chord Newton left the valid region at theta={theta:.6g}")
    r, J = system.residual_and_jacobian(x)
    if np.max(np.abs(r)) <= 10 * tol:
        return x, J
    raise LocateError(f"chord Newton did not converge at theta={theta:.6g} "
                      f"(max|r| = {np.max(np.abs(r)):.2e})")


def _tests_on_chord(J, d, scale):
    """(ψ, φ) as (sign, logdet) pairs: ψ = det[J; d^T] (branch point), φ = det A (fold)."""
    Js = J if scale is None else J * scale[None, :]
    ds = d if scale is None else d / scale          # d in scaled unknowns
    n = Js.shape[0]
    psi = lu_det(np.vstack([Js, ds[None, :] / np.linalg.norm(ds)]))[:2]
    phi = lu_det(Js[:, :n])[:2]
    return psi, phi


#: The branch must leave both ends within 60° of the chord (|cos| ≥ 0.5): then, for close
#: solutions, it is a graph over the chord and the chord orientation is the continuity one.
GRAPH_COS = 0.5


def classify(system, xa, xb, scale=None):
    """Which test function changes sign between two solutions of ``system``: 'branch point'
    (ψ = det[J; d^T] = (d·t) det[J; t^T]), 'fold' (only φ = det A), or None. Valid where the
    branch between them is a graph over the chord d = x_b − x_a (then d·t keeps its sign and ψ
    changes sign with det[J; t^T] for t oriented by continuity); two solutions whose tangent is
    more than 60° off the chord at either end are refused (:class:`LocateError`). Returns (kind, (ψ_a, ψ_b, φ_a, φ_b))
    with each value a (sign, logdet) pair."""
    xa, xb = np.asarray(xa, float), np.asarray(xb, float)
    d = xb - xa
    sc = None if scale is None else np.asarray(scale, float)
    Ja = system.residual_and_jacobian(xa)[1]
    Jb = system.residual_and_jacobian(xb)[1]
    dn = d if sc is None else d / sc
    for J, end in ((Ja, "a"), (Jb, "b")):
        Js = J if sc is None else J * sc[None, :]
        cos = abs(float(null_vector(Js) @ dn)) / float(np.linalg.norm(dn))
        if cos < GRAPH_COS:
            raise LocateError(f"the branch at x_{end} makes an angle of {math.degrees(math.acos(cos)):.0f} deg "
                              f"with the chord (> {math.degrees(math.acos(GRAPH_COS)):.0f}): the two "
                              "solutions are too far apart to bracket a fold or branch point; "
                              "take closer ones")
    psi_a, phi_a = _tests_on_chord(Ja, d, sc)
    psi_b, phi_b = _tests_on_chord(Jb, d, sc)
    if psi_a[0] * psi_b[0] < 0:
        kind = "branch point"
    elif phi_a[0] * phi_b[0] < 0:
        kind = "fold"
    else:
        kind = None
    return kind, (psi_a, psi_b, phi_a, phi_b)


def locate(system, xa, xb, scale=None, tol=1e-12, theta_tol=1e-10, max_eval=60,
           newton_tol=1e-12, newton_iter=20) -> Bifurcation:
    """Locate the fold or branch point between two solutions x_a, x_b of one system.

    The branch between them is followed on the chord hyperplanes d·(x − x_a) = θ|d|²
    (d = x_b − x_a), each solved by Newton from the nearest solved point. The test function
    that changes sign (:func:`classify`: ψ for a branch point, else φ for a fold) is driven to
    zero in θ by the Illinois variant of regula falsi, on its value sign·exp(logdet − logdet_a)
    (no overflow). Stops when the bracket is shorter than ``theta_tol`` or |test| < ``tol`` relative
    to its value at x_a. Raises :class:`LocateError` when neither changes sign.
    """
    xa, xb = np.asarray(xa, float), np.asarray(xb, float)
    kind, (psi_a, psi_b, phi_a, phi_b) = classify(system, xa, xb, scale)
    if kind is None:
        raise LocateError("no test function changes sign between the two solutions "
                          f"(det[J;d]: {psi_a[0]:+d} -> {psi_b[0]:+d}, det A: {phi_a[0]:+d} -> "
                          f"{phi_b[0]:+d}): no fold or simple branch point bracketed")
    which = 0 if kind == "branch point" else 1
    sc = None if scale is None else np.asarray(scale, float)
    d = xb - xa
    ref = (psi_a, phi_a)[which][1]

    def value(pair):
        s, lg = pair
        return s * math.exp(min(lg - ref, 700.0))

    fa, fb = value((psi_a, phi_a)[which]), value((psi_b, phi_b)[which])
    vals = {0.0: fa, 1.0: fb}
    ta, tb = 0.0, 1.0
    pts = {0.0: xa, 1.0: xb}
    side = 0
    nev = 0
    x_best, t_best, f_best = (xa, 0.0, fa) if abs(fa) < abs(fb) else (xb, 1.0, fb)
    while nev < max_eval and tb - ta > theta_tol:
        t = (ta * fb - tb * fa) / (fb - fa)
        if not ta < t < tb:
            t = 0.5 * (ta + tb)
        near = min(pts, key=lambda s: abs(s - t))
        x0 = pts[near] + (t - near) * d
        x, J = _newton_on_chord(system, x0, xa, d, t, newton_tol, newton_iter)
        pts[t] = x
        nev += 1
        f = value(_tests_on_chord(J, d, sc)[which])
        vals[t] = f
        if abs(f) < abs(f_best):
            x_best, t_best, f_best = x, t, f
        if abs(f) <= tol:
            break
        if f * fb > 0:          # Illinois: the end kept twice has its value halved
            tb, fb = t, f
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            ta, fa = t, f
            if side == 1:
                fb *= 0.5
            side = 1
    closed = tb - ta <= theta_tol
    converged = closed or abs(f_best) <= tol
    jump = closed and abs(f_best) > JUMP_TEST
    if jump:                       # where it jumps: the bracket's end, not the smallest |test|
        x_best, t_best, f_best = pts[tb], tb, vals[tb]
    return Bifurcation(kind, x_best, t_best, float(x_best[-1]), float(f_best), nev,
                       converged=bool(converged), jump=bool(jump))


# --------------------------------------------------------------------------- steady pulses
def pulse_system(pulse, params):
    """The extended steady system of a stored pulse on its own grid and pin:
    (SteadyProblem(free='both'), x = (ln v, β, q), column scale (1, …, 1, β, 1))."""
    from ..core.h5io import state_order_of
    from .equations import SteadyProblem
    from .solver import front_pin

    xi = np.asarray(pulse.xi, float)
    y = np.log(np.asarray(pulse.v, float))
    if "pin_index" in pulse.extra and "y_pin" in pulse.extra:
        k, ypin = int(pulse.extra["pin_index"]), float(pulse.extra["y_pin"])
    else:
        k, _ = front_pin(xi, y, math.log(pulse.v_stick))
        ypin = float(y[k])
    hil = str(pulse.extra.get("hilbert", "cubic"))
    prob = SteadyProblem(params, pulse.tau_d_ratio, xi, k, ypin, hilbert=hil, free="both",
                         state_order=state_order_of(pulse))
    x = np.concatenate([y, [pulse.beta, pulse.tau_d_ratio]])
    scale = np.ones(x.size)
    scale[-2] = pulse.beta
    return prob, x, scale


def pulse_solution(pulse, params):
    """A stored, converged pulse as a SteadySolution of :func:`pulse_system` (x = (ln v, β, q)),
    for the re-solves that start from one (grid convergence, a longer domain)."""
    from .newton import SolveStats
    from .solver import SteadySolution
    prob, x, _ = pulse_system(pulse, params)
    return SteadySolution(prob, x, SolveStats(True, "stored", 0, 0.0), 0.0, 0)


def unscaled_lu(lu_scaled, beta):
    """The LU of A from that of A D, D = diag(1, …, 1, β) (:func:`pulse_system`'s scale on the
    last column of A = ∂(Δ, pin)/∂(ln v, β)): A D = P L U gives A = P L (U D⁻¹), the same pivots
    with U's last column, all of it in U, divided by β."""
    lu, piv = lu_scaled
    lu = lu.copy(order="K")            # LAPACK's column order kept: no copy per solve
    lu[:, -1] /= beta
    return lu, piv


def pulse_tests(pulse, params, orient_scalars=None, singular_values=True):
    """:func:`indicators` of a converged pulse (its extended Jacobian at its stored fields).

    orient_scalars : (dβ, dq), optional: orient the tangent so that its (β, q) part (in the
        scaled unknowns (ln β, q)) has a positive product with it (the direction of the family).

    Returns (Indicators, max|r|) — the residual shows whether the stored pulse is a solution of
    the rebuilt system (it must be ~1e-13).
    """
    prob, x, scale = pulse_system(pulse, params)
    r, J = prob.residual_and_jacobian(x)
    orient = None
    if orient_scalars is not None:
        orient = np.zeros(x.size)
        orient[-2] = orient_scalars[0] / pulse.beta
        orient[-1] = orient_scalars[1]
    return indicators(J, scale, orient, singular_values), float(np.max(np.abs(r)))


def pulse_null_modes(pulse, params, k=2):
    """:func:`~slippulse.steady.null_modes.null_modes` of a stored pulse's pinned matrix A (speed
    column scaled by β): its k smallest singular values and the shifts their vectors are."""
    from .null_modes import null_modes
    prob, x, scale = pulse_system(pulse, params)
    J = prob.residual_and_jacobian(x)[1] * scale[None, :]
    n = J.shape[0]
    return null_modes(J[:, :n], prob.xi, x[:-2], params.v_star, k)


@dataclass
class ScanRow:
    label: str
    tau_d_ratio: float
    beta: float
    L: float
    n_points: int
    max_residual: float
    values: Indicators
    unstable_count: object = None   # count of real eigenvalues in (0, ∞), where a spectrum is stored
    across: str | None = None       # a sign change of det B from the row before across a change
                                    # of N, decided on one grid ('kept', 'changed', or why not)


@dataclass
class Event:
    """A sign change or a minimum between two neighbouring pulses of a scan."""
    kind: str            # 'fold', 'branch point', 'sigma minimum', 'not comparable'
    between: tuple       # (label_a, label_b)
    detail: str


def _stored_count(path, label):
    """Real eigenvalues of the pinned operator in (0, ∞) among those stored with a pulse's
    spectrum (datasets sigma_real, sigma_imag of its 'spectrum' group; real: |Im| ≤ 1e-9 |Re|),
    or None where no spectrum is stored. Only the eigenvalues the spectrum search found are
    counted (the argument-principle count, attribute 'count', is over a complex box)."""
    from ..core.h5io import open_h5
    with open_h5(path) as h5:
        grp = h5["pulses"][label]
        if "spectrum" not in grp or "sigma_real" not in grp["spectrum"]:
            return None
        sp = grp["spectrum"]
        re = np.asarray(sp["sigma_real"][...], float)
        im = np.asarray(sp["sigma_imag"][...], float) if "sigma_imag" in sp else np.zeros_like(re)
        real = np.abs(im) <= 1e-9 * np.abs(re)
        return int(np.count_nonzero(real & (re > 0)))


def scan(path, order="beta", labels=None, progress=None, singular_values=True):
    """The test functions of every converged pulse of a family file, and the events between
    neighbours.

    order : 'beta' (default; the main family's β rises monotonically from 1.33 τ_min to its deep
        end, through any fold in τ_d) or 'file' (decreasing τ_d). The tangent of each pulse is
        oriented along this order (its (ln β, q) part by the centred secant of its neighbours).

    Returns (rows, events): events are a sign change of t_q ('fold'), of det B with t oriented
    ('branch point'), both compared only between pulses of equal N ('not comparable' otherwise;
    then a fold still shows in t_q, which does not depend on N), and an interior local minimum
    of σ₁/σ₂ below 0.1 of both neighbours' ('sigma minimum': a candidate to re-examine).
    """
    from ..core import h5io
    labs = h5io.list_pulses(path) if labels is None else list(labels)
    pulses, params = [], None
    for lab in labs:
        p, params = h5io.read_pulse(path, lab)
        if p.converged:
            pulses.append(p)
    if order == "beta":
        pulses.sort(key=lambda p: p.beta)
    elif order != "file":
        raise ValueError(f"order={order!r}: must be 'beta' or 'file'")
    rows = []
    m = len(pulses)
    for i, p in enumerate(pulses):
        a, b = pulses[max(i - 1, 0)], pulses[min(i + 1, m - 1)]
        if a is b:
            orient = None
        else:
            orient = (math.log(b.beta / a.beta) * p.beta, b.tau_d_ratio - a.tau_d_ratio)
        vals, res = pulse_tests(p, params, orient, singular_values)
        rows.append(ScanRow(p.label, float(p.tau_d_ratio), float(p.beta), float(p.L),
                            int(p.n_points), res, vals, _stored_count(path, p.name or p.label)))
        if progress:
            progress(rows[-1])
    return rows, events(rows)


def events(rows):
    """Fold / branch-point / σ-minimum events between neighbouring rows of :func:`scan`."""
    out = []
    for a, b in zip(rows[:-1], rows[1:]):
        va, vb = a.values, b.values
        pair = (a.label, b.label)
        if va.t_param * vb.t_param < 0:
            out.append(Event("fold", pair, f"t_q {va.t_param:+.3e} -> {vb.t_param:+.3e}"))
        if va.bordered_sign * vb.bordered_sign < 0:
            if a.n_points == b.n_points:
                out.append(Event("branch point", pair,
                                 f"sign det B {va.bordered_sign:+d} -> {vb.bordered_sign:+d}"))
            elif b.across == "kept":
                continue                     # the same sign on one grid (FamilyMonitor)
            elif b.across == "changed":
                out.append(Event("branch point", pair, "sign det B changes on one grid, across "
                                                       f"N {a.n_points} -> {b.n_points}"))
            else:
                out.append(Event("not comparable", pair,
                                 f"sign det B {va.bordered_sign:+d} -> {vb.bordered_sign:+d} "
                                 f"across N {a.n_points} -> {b.n_points}"))
    ratios = [r.values.sigma[0] / r.values.sigma[1] if len(r.values.sigma) == 2 else math.nan
              for r in rows]
    for i in range(1, len(rows) - 1):
        if ratios[i] < 0.1 * min(ratios[i - 1], ratios[i + 1]):
            out.append(Event("sigma minimum", (rows[i - 1].label, rows[i + 1].label),
                             f"sigma1/sigma2 = {ratios[i]:.3e} at {rows[i].label}"))
    return out


#: The re-solves of a pulse on a neighbour's grid, in order: the ‖r‖₂ line search, given up
#: once it creeps, then the natural monotonicity test, which a front a few cells off the new
#: grid's fine zone does not hold back (:func:`~slippulse.steady.newton.newton`).
RESOLVE_ATTEMPTS = (("residual", 6), ("natural", 0))


def on_one_grid(pa, pb, params):
    """Pulses a and b as two solutions of one discrete system: a's extended system (its grid and
    pin, :func:`pulse_system`) and b re-solved on it at its own τ_d (β free; the interpolated
    guess is re-pinned by Newton). Returns (system, x_a, x_b, scale); raises
    :class:`LocateError` when b does not re-solve there."""
    from .solver import interpolate
    from .newton import newton
    from .equations import SteadyProblem

    prob, xa, scale = pulse_system(pa, params)
    yb = interpolate(np.asarray(pb.xi, float), np.log(np.asarray(pb.v, float)), prob.xi,
                     pb.v_stick)
    fixed = SteadyProblem(params, pb.tau_d_ratio, prob.xi, prob.pin_index, prob.y_pin,
                          hilbert=prob.hilbert, H=prob.H, state_order=prob.state_order)
    for search, creep in RESOLVE_ATTEMPTS:
        xb0, stats = newton(fixed, np.concatenate([yb, [pb.beta]]), creep=creep,
                            line_search=search)
        if stats.converged:
            return prob, xa, np.concatenate([xb0, [pb.tau_d_ratio]]), scale
    raise LocateError(f"pulse {pb.label} did not re-solve on {pa.label}'s grid: "
                      f"{stats.message}")


def locate_between_pulses(pa, pb, params, **kw) -> Bifurcation:
    """Locate a fold or branch point between two pulses (:func:`on_one_grid`, then
    :func:`locate`). The result's ``extra`` holds τ_d/τ_min, β and L (FWHM) there, the
    transversality cos(ψ, ∂F/∂q) (zero at a branch point) and what the smallest singular
    vector of A moves there (:mod:`.null_modes`)."""
    from .measures import pulse_length
    from .null_modes import null_modes, transversality

    prob, xa, xb, scale = on_one_grid(pa, pb, params)
    bif = locate(prob, xa, xb, scale=scale, **kw)
    v = np.exp(bif.x[:-2])
    J = prob.residual_and_jacobian(bif.x)[1] * scale[None, :]
    n = J.shape[0]
    lu = sla.lu_factor(J[:, :n], check_finite=False)
    mode = null_modes(J[:, :n], prob.xi, bif.x[:-2], params.v_star, k=1, lu=lu)[0]
    bif.extra = {"tau_d_ratio": float(bif.x[-1]), "beta": float(bif.x[-2]),
                 "L": float(pulse_length(prob.xi, v, params.v_star, crossings=False)),
                 "transversality": transversality(J, lu=lu), "null_mode": mode.describe()}
    return bif


def across_grid_change(pa, pb, params) -> Event | None:
    """Decide a 'not comparable' pair (neighbours on grids of different N): the coarser pulse is
    re-solved on the finer one's grid (:func:`on_one_grid`; the other way round where that
    fails) and sign det B = [J; tᵀ] of both is compared there, t oriented from a to b as in
    :func:`scan`. The sign of a determinant is a property of one discrete system, so only on
    one grid does its change mean a branch point. Returns the 'branch point' event, or None
    where the signs agree; raises :class:`LocateError` where neither re-solves."""
    fine, coarse = (pa, pb) if pa.n_points >= pb.n_points else (pb, pa)
    try:
        prob, xf, xc, scale = on_one_grid(fine, coarse, params)
    except LocateError:                   # both grids hold their pulses: try the other one
        fine, coarse = coarse, fine
        prob, xf, xc, scale = on_one_grid(fine, coarse, params)
    xa, xb = (xf, xc) if fine is pa else (xc, xf)
    orient = np.zeros(xa.size)
    orient[-2] = math.log(pb.beta / pa.beta)       # scaled unknowns: d ln β, dq
    orient[-1] = pb.tau_d_ratio - pa.tau_d_ratio
    sa = indicators(prob.residual_and_jacobian(xa)[1], scale, orient, False).bordered_sign
    sb = indicators(prob.residual_and_jacobian(xb)[1], scale, orient, False).bordered_sign
    if sa * sb < 0:
        return Event("branch point", (pa.label, pb.label),
                     f"sign det B {sa:+d} -> {sb:+d} on {fine.label}'s grid (N {fine.n_points})")
    return None


def indicator_attrs(v: Indicators) -> dict:
    """The stored form of a pulse's test functions (its ``bif_*`` attributes)."""
    out = {"bif_fold_sign": int(v.fold_sign), "bif_fold_logdet": float(v.fold_logdet),
           "bif_bordered_sign": int(v.bordered_sign),
           "bif_bordered_logdet": float(v.bordered_logdet), "bif_t_q": float(v.t_param)}
    if len(v.sigma) == 2:
        out["bif_sigma1"], out["bif_sigma2"] = map(float, v.sigma)
    return out


def write_indicators(path, rows):
    """Store the test functions of :func:`scan` rows as attributes of their pulses in ``path``
    (:func:`indicator_attrs`), atomically."""
    from ..core.h5io import atomic_update

    def fill(h5):
        for r in rows:
            h5["pulses"][r.label].attrs.update(indicator_attrs(r.values))

    atomic_update(path, fill)


class FamilyMonitor:
    """The test functions of each pulse a continuation writes, returned as its ``bif_*``
    attributes (the ``monitor`` of :func:`~slippulse.steady.continuation.run_family`).

    The tangent is oriented along the march, by the step from the previous written pulse (the
    first one: toward lower τ_d, the direction a family is continued), so that between two
    neighbours a sign change of t_q is a fold and of det B a branch point, not a flipped tangent.
    Where N changed since the previous pulse and sign det B with it, the pair is decided on one
    grid at once (:func:`across_grid_change`, stored as ``bif_across_grid``: 'kept', 'changed'
    or why it was not decided), so that no later report re-solves it. :func:`stored_rows` reads
    the attributes back for :func:`events`. A solution without a family tangent gets the one the
    fold test found (``sol.tangent``, in (y, β, q)): its grid check's normal line then needs no
    dense solve of its own, and the LU of A with it (``sol.fold_lu``: the next natural step
    factors none of its own)."""

    #: it gives a pulse without a family tangent the fold test's (run before the grid check)
    finds_tangent = True

    def __init__(self, params):
        self.params = params
        self.previous = None                  # the last pulse seen (its bif_* attributes set)

    def __call__(self, sol, pulse) -> dict:
        prev = self.previous
        if prev is None:
            orient = (0.0, -1.0)
        else:
            orient = (math.log(pulse.beta / prev.beta) * pulse.beta,
                      pulse.tau_d_ratio - prev.tau_d_ratio)
        vals, _ = pulse_tests(pulse, self.params, orient)
        if sol is not None and sol.tangent is None:
            t = np.array(vals.tangent)
            t[-2] *= pulse.beta               # the β column was scaled by β (pulse_system)
            sol.tangent = t
            if vals.lu_a is not None:         # for the next natural step (kept only there)
                sol.fold_lu = unscaled_lu(vals.lu_a, pulse.beta)
        out = indicator_attrs(vals)
        if (prev is not None and prev.n_points != pulse.n_points
                and int(prev.extra.get("bif_bordered_sign", 0)) * vals.bordered_sign < 0):
            try:
                out["bif_across_grid"] = ("changed" if across_grid_change(prev, pulse, self.params)
                                          else "kept")
            except LocateError as exc:
                out["bif_across_grid"] = f"not decided: {exc}"
        pulse.extra.update(out)
        self.previous = pulse
        return out


def stored_rows(path):
    """The test functions stored with the converged pulses of a family file (``bif_*``
    attributes), as :class:`ScanRow` by increasing β, for :func:`events`; pulses without them are
    left out (no recomputation: :func:`scan` does that)."""
    from ..core.h5io import list_pulses, read_pulse
    rows = []
    for lab in list_pulses(path):
        p, _ = read_pulse(path, lab)
        e = p.extra
        if not p.converged or "bif_t_q" not in e:
            continue
        sig = (float(e["bif_sigma1"]), float(e["bif_sigma2"])) if "bif_sigma1" in e else ()
        vals = Indicators(int(e["bif_fold_sign"]), float(e["bif_fold_logdet"]),
                          int(e["bif_bordered_sign"]),
                          float(e.get("bif_bordered_logdet", math.nan)), np.empty(0),
                          float(e["bif_t_q"]), sig, int(p.n_points))
        rows.append(ScanRow(lab, float(p.tau_d_ratio), float(p.beta), float(p.L),
                            int(p.n_points), float(p.max_residual), vals,
                            across=e.get("bif_across_grid")))
    rows.sort(key=lambda r: r.beta)
    return rows
