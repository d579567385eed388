"""The strategies of the continuation driver (:class:`~.driver.Continuation`), one job each, and
their combination (:class:`Strategy`), a value: printed, stored with every pulse it writes, and
refused when built if its parts cannot work together.

* predictor — which parameter is stepped and where the next pulse is guessed: along the
  family's arclength, :class:`TangentPredictor`, :class:`LengthPredictor`,
  :class:`SecantPredictor`; at a fixed τ_d or β, :class:`NaturalPredictor`;
* corrector — how the guess is driven to the family: :class:`NewtonCorrector` (Newton with a
  line search, optional chord start and creep stop);
* step control — how the step changes: the arclength step ds, :class:`FreeSteps`,
  :class:`HeldSteps`; τ_d to round targets, :class:`TargetSteps`; β toward 1,
  :class:`ShrinkSteps`;
* grid policy — which grid carries the next pulse: :class:`AdaptGrid`, :class:`StretchGrid`;
* grid check — how every written pulse is checked against a refined grid: :class:`NestedCheck`.

:data:`AUTO` is the product's deep combination; :data:`NATURAL` and :data:`BETA_STEPS` the
shallow ones that ``slippulse steady family`` runs first (:data:`STRATEGIES` names them).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from ..newton import LINE_SEARCHES, SOLVERS, DirectLU, KrylovLU
from .tolerance import NEWTON_TOL


class StrategyError(ValueError):
    """A strategy, or a combination of strategies, that cannot work (refused when built)."""


def describe(obj) -> str:
    """``name(field=value, ...)`` of a strategy: its name and the fields that set it."""
    parts = []
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        parts.append(f"{f.name}={v}" if not dataclasses.is_dataclass(v) else
                     f"{f.name}={describe(v)}")
    return f"{obj.name}({', '.join(parts)})"


# ------------------------------------------------------------------------------ predictors
@dataclass(frozen=True)
class TangentPredictor:
    """Predict along the family tangent: (ln(1 − β), q/κ) moved by ds along it, ln v stretched
    behind the leading edge by the change of L the tangent gives (the healing front moves by many
    of its own widths per step, which a linear tangent in ln v cannot carry)."""

    name = "tangent"

    def mode(self, ds, has_rate, has_secant) -> str:
        """The predictor used for a step of ``ds``: always the tangent."""
        return "tangent"


@dataclass(frozen=True)
class LengthPredictor:
    """On a stretched grid, move the healing-front zone by the change of L per ds of the last
    accepted step instead of the tangent's: deep in the family the tangent's change of L falls
    ≈ 13 % short, so the front lands about a cell off its nodes and the corrector creeps. Acts
    for steps ds ≤ ``ds_max`` only (larger steps, far from the family's curvature scale, fail with
    it); above, and without a last step, the tangent's.
    """

    ds_max: float = 0.002
    name = "length"

    def __post_init__(self):
        if not self.ds_max > 0:
            raise StrategyError(f"{self.name}: ds_max={self.ds_max} is invalid: must be > 0")

    def mode(self, ds, has_rate, has_secant) -> str:
        """The predictor used for a step of ``ds``: "length" with a last step's dL/ds and
        ds ≤ ``ds_max``, else "tangent"."""
        return "length" if has_rate and ds <= self.ds_max else "tangent"


@dataclass(frozen=True)
class SecantPredictor(LengthPredictor):
    """:class:`LengthPredictor`, and ln v node by node along the secant through the last two
    pulses when both lie on the same deformed grid (the last step itself "length" or "secant"):
    the starting residual falls from ~5e−5 to ~1e−7 and the corrector needs 2–3 iterations."""

    name = "secant"

    def mode(self, ds, has_rate, has_secant) -> str:
        m = super().mode(ds, has_rate, has_secant)
        return "secant" if m == "length" and has_secant else m


@dataclass(frozen=True)
class NaturalPredictor:
    """Step a natural parameter, τ_d (β unknown) or β (τ_d unknown), along the tangent at the
    fixed parameter, J_x t = −J_p, with ln v stretched behind the leading edge by the change of L
    the tangent gives (:func:`~.natural.tangent_step`). Near τ_min β and L change ever faster
    with τ_d: the τ_d steps hand over to β steps (:class:`TargetSteps` ``beta_switch``), and
    those to the arclength march (:data:`~.family.DEEP_BETA`)."""

    parameter: str = "tau_d"
    name = "natural"

    def __post_init__(self):
        if self.parameter not in ("tau_d", "beta"):
            raise StrategyError(f"natural: parameter={self.parameter!r} is invalid: must be "
                                f"'tau_d' or 'beta'")

    def mode(self, ds, has_rate, has_secant) -> str:
        """The predictor of a step: always the natural one."""
        return "natural"


PREDICTORS = {c.name: c for c in (TangentPredictor, LengthPredictor, SecantPredictor,
                                  NaturalPredictor)}


# ------------------------------------------------------------------------------ corrector
@dataclass(frozen=True)
class NewtonCorrector:
    """Damped Newton on the arclength-closed equations (:func:`~slippulse.steady.newton.newton`)
    to max|r| ≤ :data:`~.tolerance.NEWTON_TOL`.

    Attributes
    ----------
    max_iter : int
        Iterations before the attempt fails (ds is then halved).
    line_search : str
        "residual" (‖r‖₂ must fall) or "natural" (the simplified Newton correction must shrink:
        affine invariant, it takes full steps where the Jacobian is nearly singular along the
        motion of the healing front and the ‖r‖₂ test cuts every step to λ ≤ 1/4).
    creep : int
        > 0: fail as soon as max|r| has not halved over that many iterations (a step too long
        for Newton's basin fails in a few iterations instead of ``max_iter``); 0: never.
    chord : bool
        Hand the LU of the last accepted corrector to this one (with :class:`DirectLU`: chord
        iterations on it first, the Jacobian formed only when they stop contracting).
    reuse_lu : bool
        Find the next tangent by iterative refinement with the last corrector's LU
        (back-substitutions instead of a factorisation; the same tangent to ~1e−11).
    linear : how each step solves J δ = −r: :class:`~slippulse.steady.newton.KrylovLU`
        (default: GMRES on the LU in hand, which is then always handed to the corrector, ``chord``
        or not; an LU only where GMRES does not converge), or
        :class:`~slippulse.steady.newton.DirectLU` (an LU per step; ``chord``: chord iterations
        on the LU handed in first).
    """

    max_iter: int = 25
    line_search: str = "residual"
    creep: int = 0
    chord: bool = False
    reuse_lu: bool = True
    linear: DirectLU = field(default_factory=KrylovLU)
    name = "newton"

    def __post_init__(self):
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise StrategyError(f"newton: max_iter={self.max_iter!r} is invalid: must be an "
                                f"integer >= 1")
        if self.line_search not in LINE_SEARCHES:
            raise StrategyError(f"newton: line_search={self.line_search!r} is invalid: must be "
                                f"one of {LINE_SEARCHES}")
        if not (isinstance(self.creep, int) and self.creep >= 0):
            raise StrategyError(f"newton: creep={self.creep!r} is invalid: must be an integer "
                                f">= 0")
        if not isinstance(self.linear, DirectLU):
            raise StrategyError(f"newton: linear={self.linear!r} is invalid: must be DirectLU or "
                                f"KrylovLU")

    @property
    def tol(self) -> float:
        """The convergence tolerance on max|r| (the one of the whole package)."""
        return NEWTON_TOL

    def solve(self, problem, x0, lu=None, creep=None):
        """Drive ``problem`` from ``x0``; ``lu``: the LU for the chord start (used only with
        ``chord``); ``creep``: this attempt's creep stop when it differs from ``self.creep``.
        Returns (x, SolveStats) with the LU (and the Jacobian) kept for the next tangent. Newton
        is the solver registered as "newton" (:data:`~slippulse.steady.newton.SOLVERS`)."""
        krylov = isinstance(self.linear, KrylovLU)
        return SOLVERS["newton"](problem, x0, tol=NEWTON_TOL, max_iter=self.max_iter,
                      lu=lu if self.chord or krylov else None, keep=self.reuse_lu or krylov,
                      creep=self.creep if creep is None else creep,
                      line_search=self.line_search, linear=self.linear)


# ------------------------------------------------------------------------------ step control
@dataclass(frozen=True)
class FreeSteps:
    """ds grows by ``grow`` after a corrector of ≤ ``easy`` iterations, shrinks by ``shrink``
    after one of > ``hard``, halves after a failure; the march fails below ``ds_min``.

    ds : the first step; ds_min, ds_max : its bounds (in the plane (ln(1 − β), q/κ)).
    overshoot : a step whose predicted τ_d would pass the march's stop by more than this
    fraction of the distance left is shortened to pass it by that fraction (to ds_min at
    least), so that the march ends near stop; inf: never (the deep family's march, whose
    spacing of written pulses is set in L).
    """

    ds: float = 0.1
    ds_min: float = 0.004
    ds_max: float = 0.4
    grow: float = 1.5
    shrink: float = 0.7
    easy: int = 6
    hard: int = 10
    overshoot: float = math.inf
    name = "free"

    def __post_init__(self):
        if not (0 < self.ds_min <= self.ds <= self.ds_max):
            raise StrategyError(f"{self.name}: ds={self.ds}, ds_min={self.ds_min}, "
                                f"ds_max={self.ds_max} are invalid: need 0 < ds_min <= ds <= "
                                f"ds_max")
        if not (self.grow >= 1.0 and 0 < self.shrink <= 1.0 and self.easy <= self.hard):
            raise StrategyError(f"{self.name}: grow={self.grow}, shrink={self.shrink}, "
                                f"easy={self.easy}, hard={self.hard} are invalid: need grow >= 1, "
                                f"0 < shrink <= 1, easy <= hard")
        if not self.overshoot > 0:
            raise StrategyError(f"{self.name}: overshoot={self.overshoot} is invalid: must be > 0")

    def next_ds(self, ds, iterations, ds_max):
        """The step after an accepted one of ``ds`` whose corrector took ``iterations``."""
        if iterations <= self.easy:
            return min(self.grow * ds, ds_max)
        if iterations > self.hard:
            return max(self.shrink * ds, self.ds_min)
        return ds


@dataclass(frozen=True)
class HeldSteps(FreeSteps):
    """:class:`FreeSteps` until a tangent step above the predictor's ``ds_max`` has failed and the
    next accepted step was the length or secant predictor's; from then on ds is held at or below a
    cap (at first the predictor's ``ds_max``). Deep in the family the free control grows ds past
    the threshold after every easy step, where the tangent's step fails after ``max_iter``
    iterations: one attempt in three, half the wall time.

    ds_min : a tenth of the cap (the march halves ds below the cap after failures before it
        refines the healing front).
    cap_shrink : after a failure at or near the cap (ds ≥ cap_shrink · cap) the cap becomes
        cap_shrink · ds; 1: a fixed cap.
    cap_grow_after : after this many accepted steps at the cap in a row it is divided by
        ``cap_shrink`` (up to the predictor's ``ds_max``).
    corrector : the corrector once held (ds then sits at its cap whatever the iterations, so a
        chord start cannot change the path the way it does with ds free); its ``creep`` acts only
        at a ds within ``cap_shrink`` of the cap (below it, after halvings, the free corrector's).
    """

    ds_min: float = 0.0002
    cap_shrink: float = 0.8
    cap_grow_after: int = 6
    corrector: NewtonCorrector = field(default_factory=lambda: NewtonCorrector(
        line_search="natural", creep=4, chord=True))
    name = "held"

    def __post_init__(self):
        super().__post_init__()
        if not (0 < self.cap_shrink <= 1.0):
            raise StrategyError(f"held: cap_shrink={self.cap_shrink} is invalid: must be in "
                                f"(0, 1]")
        if not (isinstance(self.cap_grow_after, int) and self.cap_grow_after >= 1):
            raise StrategyError(f"held: cap_grow_after={self.cap_grow_after!r} is invalid: must "
                                f"be an integer >= 1")


@dataclass(frozen=True)
class TargetSteps:
    """τ_d steps onto the round targets start − k · ``step``: each step goes ``h`` toward the next
    target (h = ``step`` at first), halves h after a failure and doubles it (up to ``step``)
    after a success. The steps stop ("stalled") once h < ``min_step`` or β > ``beta_switch``:
    near τ_min a τ_d step moves β faster than the tangent follows, and the β steps take over.

    step : the spacing of the targets (τ_d/τ_min); min_step : None, half of it (two failed steps
        in a row); beta_switch : the β beyond which τ_d steps are not tried.
    """

    step: float = 0.005
    min_step: float | None = None
    beta_switch: float = 0.85
    name = "targets"

    def __post_init__(self):
        if not (self.step > 0 and math.isfinite(self.step)):
            raise StrategyError(f"targets: step={self.step} is invalid: must be a finite number > 0")
        if self.min_step is not None and not (0 < self.min_step <= self.step):
            raise StrategyError(f"targets: min_step={self.min_step} is invalid: must be in (0, "
                                f"step={self.step:g}]")
        if not (0 < self.beta_switch < 1):
            raise StrategyError(f"targets: beta_switch={self.beta_switch} is invalid: must be in "
                                f"(0, 1)")

    @property
    def floor(self) -> float:
        """The smallest step tried (``min_step``, or half of ``step``)."""
        return 0.5 * self.step if self.min_step is None else self.min_step


@dataclass(frozen=True)
class ShrinkSteps:
    """β steps toward 1, 1 − β ← ``shrink`` · (1 − β), until τ_d passes the next target, then
    one τ_d step onto the target from the first pulse past it, on that pulse's grid, by the
    ``landing`` corrector (if it fails: the bracketing pair interpolated in τ_d, solved on a grid
    adapted to it). After a failed β step the factor moves halfway to 1; the steps stop
    ("failed") once it would exceed ``min_shrink``.
    """

    shrink: float = 0.92
    min_shrink: float = 0.97
    landing: NewtonCorrector = field(default_factory=lambda: NewtonCorrector(
        max_iter=12, chord=True, reuse_lu=False))
    name = "shrink"

    def __post_init__(self):
        if not (0 < self.shrink < self.min_shrink < 1):
            raise StrategyError(f"shrink: shrink={self.shrink}, min_shrink={self.min_shrink} are "
                                f"invalid: need 0 < shrink < min_shrink < 1")
        if not isinstance(self.landing, NewtonCorrector):
            raise StrategyError(f"shrink: landing={self.landing!r} is invalid: must be a "
                                f"NewtonCorrector")


# ------------------------------------------------------------------------------ grid policies
@dataclass(frozen=True)
class AdaptGrid:
    """Keep the grid (and its Hilbert matrix) while L stays within ``regrid`` of the L it was laid
    out for; then lay out a grid adapted to the pulse, ``n_points`` nodes (None: the start's;
    ``n_points_above`` where β > ``beta_above``, if given), ln v interpolated onto it."""

    regrid: float = 0.05
    n_points: int | None = None
    n_points_above: int | None = None
    beta_above: float = 0.7
    name = "adapt"

    def __post_init__(self):
        if not self.regrid > 0:
            raise StrategyError(f"adapt: regrid={self.regrid} is invalid: must be > 0")
        for what in ("n_points", "n_points_above"):
            n = getattr(self, what)
            if n is not None and not (isinstance(n, int) and n >= 2):
                raise StrategyError(f"adapt: {what}={n!r} is invalid: must be an integer >= 2 "
                                    f"or None")

    def points(self, beta: float, start: int) -> int:
        """The nodes of a grid laid out at β (``start``: the start's N)."""
        if self.n_points_above is not None and beta > self.beta_above:
            return self.n_points_above
        return start if self.n_points is None else self.n_points


@dataclass(frozen=True)
class StretchGrid:
    """Deform the current grid with the pulse every step (:func:`~.stretch.stretch_grid`): the
    leading-edge zone (``front_zone`` · L) kept, the zone about the healing front
    (``back_zone`` · L) moved rigidly, the body lengthened; ln v kept node by node. No
    interpolation, so no jump of the discrete family at a regrid.

    relay, relay_levels : where the corrector fails at ds_min, re-solve the current pulse with the
        cells of its healing front's steep drop split into 2**relay_levels
        (:func:`~.relay.refine_front`), check and write it, and go on from it; at most ``relay``
        times a run, never twice without an accepted step between (0: off).
    recentre : after every written pulse that passed its check, move the healing-front zone back
        onto the steep drop when they lie more than ``recentre`` · L apart
        (:func:`~.relay.recentre`): each step moves the zone by the predicted change of L, and the
        drop wanders off the cells laid out for it, whatever the step control (measured without
        it from scratch: 2 % of L ahead by 2.3 km, the checks failing from 2.96 km) (0: off).
    """

    front_zone: float = 0.01
    back_zone: float = 0.05
    relay: int = 20
    relay_levels: int = 2
    recentre: float = 0.001
    name = "stretch"

    def __post_init__(self):
        if not (0 < self.front_zone < 1 and 0 < self.back_zone < 1):
            raise StrategyError(f"stretch: front_zone={self.front_zone}, back_zone="
                                f"{self.back_zone} are invalid: must be in (0, 1) (fractions of L)")
        if not (self.relay >= 0 and self.relay_levels >= 1 and self.recentre >= 0):
            raise StrategyError(f"stretch: relay={self.relay}, relay_levels={self.relay_levels}, "
                                f"recentre={self.recentre} are invalid: need relay >= 0, "
                                f"relay_levels >= 1, recentre >= 0")


# ------------------------------------------------------------------------------ grid check
@dataclass(frozen=True)
class NestedCheck:
    """Every written pulse re-solved on its own grid with the midpoints inserted (2N − 1), on the
    line normal to the family tangent, by Newton to :data:`~.tolerance.NEWTON_TOL`, and its change
    of β and L at fixed τ_d held to the :class:`~.tolerance.GridTolerance`
    (:func:`~.gridcheck.check_pulse`).

    linear : the re-solves' linear solve (:class:`~slippulse.steady.newton.DirectLU` or
        :class:`~slippulse.steady.newton.KrylovLU`). The LU is in single precision: LAPACK
        sgetrf, half the time of dgetrf (7.5 against 14 s at 10123 points on one core); the
        residual, the iterates and the convergence test stay in double, so the re-solve meets the
        same tolerance and the check's (Δβ, ΔL/L) are those of a double LU to round-off
        (BENCHMARKS.md "Family"). With Krylov steps the next pulse's check solves on the last
        check's LU (the deep march's checks, same N, :func:`~.gridcheck.grid_change` ``warm``).
    """

    linear: DirectLU = field(default_factory=lambda: KrylovLU("single"))
    name = "nested"

    def __post_init__(self):
        if not isinstance(self.linear, DirectLU):
            raise StrategyError(f"nested: linear={self.linear!r} is invalid: must be DirectLU or "
                                f"KrylovLU")


# ------------------------------------------------------------------------------ step guard
@dataclass(frozen=True)
class SignGuard:
    """Refuse a step that leaves the branch it marches on: one across which the sign of
    det [J; r] changes (J the extended Jacobian at the new pulse, r the arclength row of the
    step, from the last tangent). Along one branch that sign is constant, folds
    included, where the bordered matrix is regular (docs/branches.md §1); it changes where a step
    lands on the far side of a fold's tip or on another branch (a jump), and where the branch
    crosses a branch point. A changed step is re-taken at half ds while ds/2 ≥ ``floor``; a
    change that persists below is a branch point crossed: accepted, and counted
    (``Continuation.sign_changes``). The matrix is the corrector's own [J; r] (r its arclength
    row, the current tangent's); its sign is read off the corrector's LU where refinement on it
    converges, else costs one LU. Signs compare on one discretisation only: on a new grid (a
    re-lay, a refined or replaced pulse) the reference is taken afresh, by the next step.
    """

    floor: float = 0.002
    name = "sign-guard"

    def __post_init__(self):
        if not (self.floor > 0 and math.isfinite(self.floor)):
            raise StrategyError(f"sign-guard: floor={self.floor!r} is invalid: must be a finite "
                                "number > 0")

    def judge(self, before, after, ds) -> str:
        """The verdict on a converged step of ``ds`` whose sign went from ``before`` (None: no
        sign to compare on this discretisation) to ``after``: "keep", "retake" (changed, and
        ds/2 ≥ floor) or "branch point" (changed below)."""
        if before is None or after == before:
            return "keep"
        return "retake" if 0.5 * ds >= self.floor else "branch point"


# ------------------------------------------------------------------------------ combination
@dataclass(frozen=True)
class Strategy:
    """A combination of a predictor, a corrector, a step control, a grid policy and a grid check.
    Refused when built (:class:`StrategyError`) if they cannot work together:

    * the length and secant predictors move the healing-front zone of a stretched grid: they need
      :class:`StretchGrid`;
    * :class:`HeldSteps` caps ds where the length or secant predictor acts, on a stretched grid:
      it needs both, and a ds_min below that cap (the predictor's ds_max);
    * the natural predictor steps τ_d to round targets (:class:`TargetSteps`) or β toward 1
      (:class:`ShrinkSteps`) on adapted grids (:class:`AdaptGrid`), and only it does;
    * a :class:`SignGuard` re-takes arclength steps: it needs an arclength predictor, and a
      ``floor`` at or above the steps' ds_min (the march would fail before it decides).
    """

    predictor: object = field(default_factory=TangentPredictor)
    corrector: NewtonCorrector = field(default_factory=NewtonCorrector)
    steps: FreeSteps = field(default_factory=FreeSteps)
    grid: object = field(default_factory=AdaptGrid)
    check: NestedCheck = field(default_factory=NestedCheck)
    guard: SignGuard | None = None

    def __post_init__(self):
        kinds = ((self.predictor, (TangentPredictor, LengthPredictor, NaturalPredictor),
                  "predictor"),
                 (self.corrector, (NewtonCorrector,), "corrector"),
                 (self.steps, (FreeSteps, TargetSteps, ShrinkSteps), "steps"),
                 (self.grid, (AdaptGrid, StretchGrid), "grid"),
                 (self.check, (NestedCheck,), "check"))
        for obj, cls, what in kinds:
            if not isinstance(obj, cls):
                raise StrategyError(f"{what}={obj!r} is invalid: must be one of "
                                    f"{', '.join(c.__name__ for c in cls)}")
        if self.guard is not None:
            if not isinstance(self.guard, SignGuard):
                raise StrategyError(f"guard={self.guard!r} is invalid: must be None or SignGuard")
            if isinstance(self.predictor, NaturalPredictor):
                raise StrategyError("guard=sign-guard re-takes arclength steps: it needs an "
                                    "arclength predictor, not natural")
            if self.guard.floor < getattr(self.steps, "ds_min", 0.0):
                raise StrategyError(f"guard=sign-guard: floor={self.guard.floor:g} must be at "
                                    f"least the steps' ds_min={self.steps.ds_min:g}")
        natural_steps = {"tau_d": TargetSteps, "beta": ShrinkSteps}
        if isinstance(self.predictor, NaturalPredictor):
            need = natural_steps[self.predictor.parameter]
            if not (isinstance(self.steps, need) and isinstance(self.grid, AdaptGrid)):
                raise StrategyError(f"predictor natural(parameter={self.predictor.parameter}) "
                                    f"steps on adapted grids: it needs steps={need.__name__}() "
                                    f"and grid=AdaptGrid()")
            return
        if isinstance(self.steps, (TargetSteps, ShrinkSteps)):
            raise StrategyError(f"steps={self.steps.name} steps a natural parameter: it needs "
                                f"predictor=NaturalPredictor()")
        stretch = isinstance(self.grid, StretchGrid)
        if isinstance(self.predictor, LengthPredictor) and not stretch:
            raise StrategyError(f"predictor {self.predictor.name!r} moves the healing-front zone "
                                f"of a stretched grid: it needs grid=StretchGrid()")
        if isinstance(self.steps, HeldSteps):
            if not (stretch and isinstance(self.predictor, LengthPredictor)):
                raise StrategyError("steps=held caps ds where the length or secant predictor "
                                    "acts on a stretched grid: it needs predictor=length or "
                                    "secant and grid=StretchGrid()")
            if not self.steps.ds_min < self.predictor.ds_max:
                raise StrategyError(f"steps=held: ds_min={self.steps.ds_min:g} must be below the "
                                    f"cap it holds ds at, the {self.predictor.name} predictor's "
                                    f"ds_max={self.predictor.ds_max:g}")

    @property
    def parameter(self) -> str:
        """What a step moves: "arclength", or the natural parameter "tau_d" or "beta"."""
        return getattr(self.predictor, "parameter", "arclength")

    @property
    def held(self) -> bool:
        """Whether the step control may hold ds at a cap."""
        return isinstance(self.steps, HeldSteps)

    @property
    def stretch(self) -> bool:
        """Whether the grid is deformed with the pulse."""
        return isinstance(self.grid, StretchGrid)

    def corrector_for(self, held: bool) -> NewtonCorrector:
        """The corrector of a step: the held one once the steps are held."""
        return self.steps.corrector if held and self.held else self.corrector

    def replace(self, **parts) -> "Strategy":
        """A copy with some parts replaced (checked again)."""
        return dataclasses.replace(self, **parts)

    def __str__(self):
        parts = (self.predictor, self.corrector, self.steps, self.grid, self.check, self.guard)
        return " + ".join(describe(p) for p in parts if p is not None)


#: The product's combination: the deep family from β ≈ 0.99 toward τ̃*, on a grid deformed with
#: the pulse, with the secant predictor below ds = 0.002, the step held there once the tangent's
#: larger steps fail (down to ds_min = 0.0002, a tenth of that cap, before the healing front is
#: refined), and the held corrector's chord start, natural line search and creep stop; every
#: written pulse (the natural steps' too) checked at 2N − 1 with a single-precision LU.
AUTO = Strategy(predictor=SecantPredictor(ds_max=0.002),
                corrector=NewtonCorrector(max_iter=25),
                steps=HeldSteps(ds=0.1, ds_min=0.0002, ds_max=0.4, cap_shrink=0.8,
                                cap_grow_after=6,
                                corrector=NewtonCorrector(max_iter=25, line_search="natural",
                                                          creep=4, chord=True)),
                grid=StretchGrid(front_zone=0.01, back_zone=0.05, relay=20, relay_levels=2,
                                 recentre=0.001),
                check=NestedCheck(KrylovLU("single")))

#: The natural steps re-lay the grid once L differs from the L it was laid out for by more than
#: this fraction.
REGRID = 0.1

#: Grid points per pulse of the family by default: (while β ≤ FAMILY_POINTS_BETA, beyond). With
#: the order-4 state both are within 1e-5 in β and 1e-4 in L of N = 4000 (docs/steady.md §3.3);
#: N = 1000 leaves ripples of 0.05 in ln v behind the peak near τ_min (20 "humps" at 1.015; τ_d
#: steps to 1.03 rejected as 11- and 2-hump solutions, measured); 1250 not (one hump at
#: 1.03–1.015, within 8.8e-7 in β and 1.2e-5 in L of N = 4000, BENCHMARKS.md), nor 1500.
FAMILY_POINTS = (1000, 1250)
FAMILY_POINTS_BETA = 0.7

#: The shallow family's τ_d steps: onto the targets 0.005 apart, tangent predictor, chord start
#: on the tangent's LU (converging steps take ≤ 6 iterations), grids of :data:`FAMILY_POINTS`
#: re-laid once L has moved by :data:`REGRID`.
NATURAL = Strategy(predictor=NaturalPredictor("tau_d"),
                   corrector=NewtonCorrector(max_iter=12, chord=True, reuse_lu=False),
                   steps=TargetSteps(step=0.005, beta_switch=0.85),
                   grid=AdaptGrid(regrid=REGRID, n_points=FAMILY_POINTS[0],
                                  n_points_above=FAMILY_POINTS[1], beta_above=FAMILY_POINTS_BETA))

#: Where the τ_d steps stall (β > 0.85): β steps toward 1 past each target, then onto it.
BETA_STEPS = Strategy(predictor=NaturalPredictor("beta"),
                      corrector=NewtonCorrector(max_iter=40, chord=True, reuse_lu=False),
                      steps=ShrinkSteps(shrink=0.92, min_shrink=0.97,
                                        landing=NewtonCorrector(max_iter=12, chord=True,
                                                                reuse_lu=False)),
                      grid=AdaptGrid(regrid=REGRID, n_points=FAMILY_POINTS[1]))

#: :data:`AUTO` whose last step ends near its stop (``steady family --from-pulse``: a stored pulse
#: continued to --to, where the first steps of ds = 0.1 would carry it far past).
FROM_PULSE = AUTO.replace(steps=dataclasses.replace(AUTO.steps, overshoot=0.5))

#: Another branch from a stored pulse (``steady family --from-pulse`` of a pulse off the deep
#: main family): free steps with the tangent predictor on the pulse's own grid, deformed with it,
#: the last step ending near --to. :data:`AUTO`'s held cap (ds ≤ 0.002 in (ln(1 − β), q/κ)) is
#: the deep family's scale: on the two-hump branch at β ≈ 0.9 it moves β by 2e−4 per step
#: (1.0193 → 1.0222 τ_min in 10 min, measured), this combination 1.0193 → 1.0301 in 3 min.
#: The sign guard: near the two-hump branch's first fold (1.01867 τ_min) the unguarded march
#: landed once on the fold's far side and came back at the next step (1.019381 τ_min, a 13-
#: iteration corrector; det [J; t] changes sign there and back, docs/branches.md §1).
BRANCH = Strategy(predictor=TangentPredictor(), corrector=NewtonCorrector(max_iter=25),
                  steps=FreeSteps(ds=0.02, ds_min=0.001, ds_max=0.1, overshoot=0.5),
                  grid=StretchGrid(), check=NestedCheck(), guard=SignGuard(floor=0.002))

#: Named combinations (``STRATEGIES["auto"]`` is :data:`AUTO`, the deep march).
STRATEGIES = {"auto": AUTO, "natural": NATURAL, "beta": BETA_STEPS, "from-pulse": FROM_PULSE,
              "branch": BRANCH}
