"""The continuation driver: :class:`Continuation`, the march of the family built from a
:class:`~.strategy.Strategy` — natural steps in τ_d or β on adapted grids, or pseudo-arclength
steps toward β → 1 — with its state, status and counters on the object (in the
style of scipy's ``OdeSolver``: ``step()`` advances by one accepted pulse, ``status`` says
whether it may go on, ``message`` says why not).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..equations import SteadyProblem
from ..measures import pulse_length
from ..newton import KrylovLU, SolveStats
from ..solver import GridSpec, SteadySolution, count_humps, front_pin, regrid_guess
from .arclength import (ArclengthProblem, bordered_sign, family_tangent, tangent_by_refinement,
                        tangent_matrix, unit_tangent)
from .natural import PulseOnGrid, judge_pulse, solve_between, tangent_step
from .relay import recentre, refine_front, zone_offset
from .strategy import AUTO, ShrinkSteps, Strategy, TargetSteps
from .stretch import stretch_grid, stretch_profile
from .tolerance import GRID_TOLERANCE, RESOLVE_CHANGE, GridTolerance


#: The march runs at most this many written pulses ahead of checks beside it: beyond, it waits
#: for the oldest (the checks are the slower stage; a longer lead is only lost where a check
#: replaces its pulse).
LEAD = 2
#: The same for natural steps, which never go back to a replaced pulse: a lead only absorbs the
#: spread of step and check times (with LEAD the shallow march waited 2.3 s of its 18 s).
NATURAL_LEAD = 8


@dataclass
class Accepted:
    """What ``on_accept`` returns for a pulse it wrote: whether it passed (its grid check), and
    the pulse written (e.g. the refined pulse of the check), which the march continues from when
    it passed."""

    passed: bool
    sol: SteadySolution
    message: str = ""


class Continuation:
    """Continuation of the family in q = τ_d/τ_min, by the step its strategy's predictor names:

    * arclength (:class:`~.strategy.TangentPredictor` and its kin): pseudo-arclength steps ds in
      (a, q/κ), a = ln(1 − β), toward β → 1 or toward ``stop``, through folds of τ_d;
    * natural τ_d (:class:`~.strategy.NaturalPredictor` with :class:`~.strategy.TargetSteps`):
      steps onto the round ``targets``, every accepted pulse handed over;
    * natural β (with :class:`~.strategy.ShrinkSteps`): β steps until τ_d passes ``targets[0]``
      (the pulses above it handed over), then the pulse at that target.

    :meth:`resume_step`, :meth:`hold`, :meth:`replace`, :meth:`restart` and
    :meth:`recentre_front` act on arclength steps only.

    Parameters
    ----------
    params : Parameters
    start : SteadySolution (of ``free="both"``, x = (y, β, q), for arclength steps), a
        :class:`~.natural.PulseOnGrid` (natural steps), or a tuple (xi, y, β, q) (arclength: the
        pin is then put at the leading edge, :func:`front_pin`; natural: the first step lays out
        a grid).
    strategy : :class:`~.strategy.Strategy` (default :data:`~.strategy.AUTO`).
    spec : layout of re-laid grids (:class:`~.strategy.AdaptGrid`).
    stop : arclength: the march is ``"finished"`` once τ_d/τ_min has reached stop from the side
        it starts on, and its first step heads for it (stop = −inf: toward β → 1); through a
        fold, where τ_d turns, it goes on along the family, and is ``"stopped"`` once τ_d has
        come back past the start's on the fold's other side (the branch does not reach stop).
    targets : natural steps: the τ_d/τ_min values to write pulses at, descending.
    beta_cap : natural steps: the march is ``"capped"`` once β ≥ beta_cap (where the arclength
        steps take over).
    max_length : arclength: the march is ``"stopped"`` once L ≥ max_length (m).
    spacing : arclength: hand an accepted pulse to ``on_accept`` only once L has changed by this
        fraction since the last one handed, growing or (on a branch followed toward shorter
        pulses) shrinking, |ln(L/L_last)| ≥ ln(1 + spacing) (0: every one); the pulse the march
        ends on always is.
    on_attempt : callable(tau_d_ratio, pulse_or_None, message), optional; after every attempt
        (steps, relays, recentring re-solves).
    on_accept : callable(solution, extra) → :class:`Accepted` or None, optional: the place where
        each accepted pulse is written (and grid-checked, or monitored); ``extra`` holds the
        driver's attributes for the pulse (strategy, step control state, relay figures). The
        march goes on from the returned pulse when it passed. A pending result (with ``done``,
        ``result`` and ``discard``, :class:`~.beside.Pending`: the check runs beside the march)
        is collected in order, up to :data:`LEAD` pulses behind the march; where it brings a
        refined pulse the march goes back to it.
    log : callable(str), optional; one line per relay or recentring.

    Attributes
    ----------
    status : "running", "finished" (stop, or the last target, reached), "stopped" (max_length),
        "failed" (ds fell below ``ds_min`` and no relay helped, or the β steps or the solve at
        the target failed; ``message`` says where and why), "stalled" (natural τ_d steps: the
        step fell below ``min_step`` or β passed ``beta_switch``), "capped" (β ≥ ``beta_cap``).
    sol : the current pulse (x = (y, β, q)); q, beta, L : its τ_d/τ_min, β and length (m).
    ds : the next arclength step; held, cap : whether the step control holds ds, and its cap.
    tangent : (t_a, t_Q) of the last accepted step; fold : τ_d/τ_min where τ_d first turned
        (moved away from ``stop``); direction : −1 (τ_d falling toward stop) or +1.
    n_steps, n_attempts, n_failed, n_iterations, n_relays, n_recentred, n_written : counters.
    last_predictor : "tangent", "length", "secant" or "natural", the predictor of the last
        attempt.
    humps : the hump count of the start pulse: a step is accepted only at that count
        (:func:`~.natural.judge_pulse`; the main family's one, another branch's its own).
    current, targets, h, shrink : natural steps: the current pulse on its grid, the targets not
        yet reached, the next τ_d step, the β steps' factor.

    """

    def __init__(self, params, start, strategy: Strategy = AUTO, spec=GridSpec(),
                 stop=-math.inf, max_length=math.inf, spacing=0.0, on_attempt=None,
                 on_accept=None, log=None, targets=(), beta_cap=math.inf):
        if not isinstance(strategy, Strategy):
            raise TypeError(f"strategy={strategy!r}: must be a Strategy")
        self.params, self.spec, self.strategy = params, spec, strategy
        self.stop, self.max_length, self.spacing = stop, max_length, spacing
        self.on_attempt, self.on_accept, self.log = on_attempt, on_accept, log
        self.status, self.message = "running", ""
        self.n_steps = self.n_attempts = self.n_failed = self.n_iterations = 0
        self.n_relays = self.n_recentred = self.n_written = 0
        # pulses handed to checks beside the march, not yet written: (Pending, the pulse handed
        # or None for natural steps, which never go back, what the march had learnt by it)
        self._pending = []
        if strategy.parameter != "arclength":
            self._start_natural(start, targets, beta_cap)
            return
        if isinstance(start, SteadySolution):
            base, x = start.problem, np.asarray(start.x, float).copy()
        else:
            xi, y, beta, q = start
            k, _ = front_pin(xi, y, math.log(params.v_stick(q * params.tau_min)))
            base = SteadyProblem(params, q, xi, k, float(y[k]), free="both")
            x = np.concatenate([y, [beta, q]])
        grid = strategy.grid
        self.n_points = (base.n if strategy.stretch or grid.n_points is None else grid.n_points)
        self._base, self._x = base, x
        self.beta, self.q = float(x[-2]), float(x[-1])
        self.q_start = self.q
        # κ: |dq/da| at the start, so that one unit of ds moves a and q/κ alike
        n0 = family_tangent(base, x, (1.0, 0.0, 1.0))
        self.kappa = max(abs(n0[-1] / (-n0[-2] / (1.0 - self.beta))), 1e-5)
        # the first step toward stop in τ_d (stop = −inf: toward β → 1)
        self.direction = 1.0 if stop > self.q else -1.0
        c_b = -1.0 if math.isfinite(stop) and self.direction * n0[-1] < 0 else 1.0
        self._orient = (c_b, 0.0, self.kappa)
        self.ds = strategy.steps.ds
        self.L = self._L_grid = pulse_length(base.xi, np.exp(x[:-2]), params.v_star,
                                             crossings=False)
        self.sol = SteadySolution(base, x, SolveStats(True, "start", 0, 0.0), 0.0, 0)
        self.humps = max(1, count_humps(np.exp(x[:-2])))     # the branch's (judge_pulse)
        self.tangent = (math.nan, math.nan)
        self.fold = None
        self.last_predictor = "tangent"
        # the history of the length and secant predictors: dL/ds of the last accepted step
        # (kept across replace/restart: those re-solve the same pulse on another grid); (x, ds)
        # of the pulse before the current one, kept while the current grid is its deformed one
        self._rate = None
        self._prev = None
        # the sign guard: the τ_d where a change of sign persisted (branch points); the sign at
        # the current pulse is _sign (None: not yet on this grid)
        self.sign_changes = []
        self._forget()
        self._candidate = (None, None, None)
        # held steps: a tangent step above the predictor's ds_max failed since the last
        # accepted step; held: ds capped from then on
        self._tangent_failed = False
        self.held = False
        self.cap = getattr(strategy.predictor, "ds_max", math.inf)
        self._at_cap = 0
        self._relaid_at = None
        self._last_written_L = self.L
        self._started = False

    # ---------------------------------------------------------------- state a resume restores
    def resume_step(self, beta_prev, q_prev, L_prev=None):
        """Go on at the pace of the march that wrote the pulse before the start (β_prev,
        τ_d/τ_min = q_prev, length L_prev): ds is the step between the two in this march's plane,
        clipped to [ds_min, ds_max], and dL/ds between them seeds the length predictor; with held
        steps the first step is at most the predictor's ds_max (a file's last two pulses are
        usually several steps apart, and the tangent's step from that distance fails)."""
        st, pred = self.strategy.steps, self.strategy.predictor
        da = math.log(1.0 - self.beta) - math.log(1.0 - beta_prev)
        dq = (self.q - q_prev) / self.kappa
        ds = math.hypot(da, dq)
        if math.isfinite(ds) and ds > 0:
            self.ds = min(max(ds, st.ds_min), st.ds_max)
            if L_prev is not None and math.isfinite(L_prev):
                self._rate = (self.L - L_prev) / ds
                if self.strategy.held:
                    self.ds = max(min(self.ds, pred.ds_max), st.ds_min)
        return self.ds

    def hold(self, cap=None):
        """Start held (the pulse resumed from was written by a held march), with its ``cap``."""
        if not self.strategy.held:
            return
        st, pred = self.strategy.steps, self.strategy.predictor
        self.held = True
        if cap is not None and math.isfinite(cap):
            self.cap = min(max(float(cap), st.ds_min), pred.ds_max)
            self.ds = min(self.ds, self.cap)

    def state_attrs(self) -> dict:
        """The driver's attributes of a written pulse: its strategy, the predictor and Newton
        iterations of the step that produced it, and the step control state (what a resumed march
        restores, :meth:`resume_step`, :meth:`hold`); of a natural step, the parameter it stepped
        ("tau_d", or "beta" for a pulse between targets) and the strategy."""
        if self.strategy.parameter != "arclength":
            return {"continuation": self._method, "continuation_strategy": str(self.strategy)}
        out = {"continuation": "arclength", "continuation_strategy": str(self.strategy),
               "continuation_predictor": self.last_predictor,
               "continuation_iterations": int(self.sol.stats.iterations),
               "march_held": bool(self.held), "march_cap": float(self.cap)}
        if self.strategy.guard is not None:
            out["march_sign_changes"] = len(self.sign_changes)
        return out

    # ---------------------------------------------------------------- the public step
    def step(self):
        """Advance by one accepted pulse and hand it to ``on_accept`` when it is due (natural
        steps: every one; arclength: per ``spacing``, then keep the healing-front zone on its
        drop). Returns None, or the message once the march failed. Raises RuntimeError when the
        march is not running."""
        if self.status != "running":
            raise RuntimeError(f"Continuation.step() with status {self.status!r}")
        if self.strategy.parameter != "arclength":
            return self._natural_step()
        if not self._started:
            self._started = True
            self.recentre_front()
        if self._collect(upto=LEAD - 1):
            return None                    # a check refined the grid: on from its pulse
        if self.advance() is not None:
            # the corrector stalled at ds_min: refine the healing front and go on from there
            if not self._relay():
                return self.message
            return None
        if (self.status == "running"
                and abs(math.log(self.L / self._last_written_L)) < math.log1p(self.spacing)):
            return None                    # a continuation step, not written (spacing)
        self.sol.tangent = self._tangent()     # the next step's, and the check's normal line
        res = self._hand(self.sol, {})
        if hasattr(res, "discard"):        # checked beside the march: on as if it passed
            self._pending.append((res, self.sol, self._step_state()))
            self.recentre_front()
        elif res is not None and res.passed:
            if res.sol is not self.sol:
                self.replace(res.sol)
            self.recentre_front()
        return None

    def run(self) -> str:
        """Step until the march is no longer running and every pulse handed is written;
        returns the status."""
        while True:
            while self.status == "running":
                self.step()
            if not self._collect():
                return self.status

    #: What the march has learnt by a pulse (:meth:`_collect` restores it when the march goes back
    #: to that pulse, so that it goes on as if it had waited for its check): the step control,
    #: the tangent's orientation and the LU in hand (a Krylov corrector's next steps, and so the
    #: step control, depend on which LU preconditions them).
    STEP_STATE = ("ds", "_rate", "tangent", "fold", "held", "cap", "_at_cap", "_tangent_failed",
                  "last_predictor", "_orient", "_lu")

    def _step_state(self) -> dict:
        return {k: getattr(self, k) for k in self.STEP_STATE}

    def _collect(self, upto: int = 0) -> bool:
        """Write the pulses whose checks beside the march are done, in order, waiting while more
        than ``upto`` are pending. Where a check refined the grid (its pulse is not the one
        handed), the march goes back to that pulse and the pulses handed after it are dropped
        unwritten. Returns whether the march went back."""
        while self._pending:
            pend, handed, state = self._pending[0]
            if len(self._pending) <= upto and not pend.done():
                return False
            self._pending.pop(0)
            res = pend.result()
            if handed is None or not res.passed or res.sol is handed:
                continue
            for later, _, _ in self._pending:
                later.discard()
            self._pending.clear()
            self.status, self.message = "running", ""
            self.replace(res.sol)
            self.__dict__.update(state)        # the step control as it was at that pulse
            self._update_status()
            self._last_written_L = self.L
            self.recentre_front()
            return True
        return False

    # ---------------------------------------------------------------- natural steps
    def _start_natural(self, start, targets, beta_cap):
        """The state of natural steps: the pulse on its grid, the targets, the step h (τ_d) or
        the factor of 1 − β (β)."""
        if isinstance(start, SteadySolution):
            self.sol, current = start, PulseOnGrid.of(start, start.to_pulse().L)
        elif isinstance(start, PulseOnGrid):
            self.sol, current = None, start
        else:
            xi, y, beta, q = start
            self.sol, current = None, PulseOnGrid(xi, np.asarray(y, float), beta, q)
        self.humps = max(1, count_humps(np.exp(current.y)))    # the branch's (judge_pulse)
        self.targets = [float(t) for t in targets]
        if not self.targets:
            raise ValueError("natural steps need targets (tau_d/tau_min values to reach)")
        self.beta_cap = beta_cap
        steps = self.strategy.steps
        self.h = steps.step if isinstance(steps, TargetSteps) else math.nan
        self.shrink = steps.shrink if isinstance(steps, ShrinkSteps) else math.nan
        self._tried = set()
        self._method = self.strategy.parameter
        self._n_start = current.xi.size
        self.last_predictor = "natural"
        self._set_current(current, math.nan)

    def _set_current(self, current: PulseOnGrid, L):
        self.current = current
        self.beta, self.q, self.L = float(current.beta), float(current.q), float(L)

    def _natural_step(self):
        """One accepted natural pulse, handed to ``on_accept``; the march goes on from that pulse
        on its grid, whatever ``on_accept`` returns (a check's refined pulse lies on 2N − 1
        points, a grid the natural steps' policy does not lay out). Returns None, or the message
        once the march failed."""
        if isinstance(self.strategy.steps, TargetSteps):
            accepted = self._step_to_target()
        else:
            accepted = self._step_in_beta()
        if accepted:
            self.n_steps += 1
            res = self._hand(self.sol, {})
            if self.current.lu_a is None:       # the fold test's LU of A, if it ran on the pulse
                # (moved, not shared: a pending check keeps the solution, not its LU)
                self.current.lu_a, self.sol.fold_lu = self.sol.fold_lu, None
            if hasattr(res, "discard"):
                self._pending.append((res, None, None))
                self._collect(upto=NATURAL_LEAD - 1)
        return self.message if self.status == "failed" else None

    def _points(self):
        """N of a grid laid out at the current β (the grid policy's)."""
        return self.strategy.grid.points(self.beta, self._n_start)

    def _tried_natural(self, value, sol, pulse, msg):
        """Count an attempt at ``value`` and tell ``on_attempt``."""
        self.n_attempts += 1
        self.n_iterations += sol.stats.iterations
        self.message = msg
        if pulse is None:
            self.n_failed += 1
        if self.on_attempt:
            self.on_attempt(value, pulse, msg)

    def _step_to_target(self) -> bool:
        """:class:`~.strategy.TargetSteps`: a τ_d step of h toward the next target, h halved after
        a failure (a trial from the same pulse to the same τ_d is not repeated) and doubled up to
        ``step`` after a success. Returns whether a pulse was accepted."""
        st, grid = self.strategy.steps, self.strategy.grid
        while True:
            if self._tau_steps_end(st):
                return False
            target = self.targets[0]
            trial = max(target, round(self.q - self.h, 10))
            if (self.q, trial) in self._tried:
                self.h *= 0.5
                continue
            self._tried.add((self.q, trial))
            # predict along the tangent at fixed τ_d, correct (chord start on its LU)
            sol, new = tangent_step(self.params, self.current, trial, "tau_d", self._points(),
                                    self.spec, regrid=grid.regrid,
                                    corrector=self.strategy.corrector)
            pulse, ok, msg = judge_pulse(sol, self.humps)
            self._tried_natural(trial, sol, pulse if ok else None, msg)
            if not ok:
                self.h *= 0.5
                continue
            self._accept_natural(sol, new, pulse.L, "tau_d")
            if abs(trial - target) < 1e-12:
                self.targets.pop(0)
            self.h = min(st.step, 2.0 * self.h)
            if not self.targets:
                self.status = "finished"
                self.message = f"reached tau_d/tau_min={self.q:.6f}"
            return True

    def _tau_steps_end(self, st) -> bool:
        """Whether the natural τ_d steps end here: no target left, β at the cap, or stalled."""
        if not self.targets:
            self.status, self.message = "finished", f"reached tau_d/tau_min={self.q:.6f}"
        elif self.beta >= self.beta_cap:
            self.status = "capped"
            self.message = f"beta={self.beta:.6f} reached the natural steps' cap {self.beta_cap}"
        elif self.h < st.floor - 1e-15 or self.beta > st.beta_switch:
            self.status = "stalled"
            self.message = (f"tau_d steps stalled at tau_d/tau_min={self.q:.6f}, beta="
                            f"{self.beta:.6f} (step {self.h:.3g}, smallest {st.floor:.3g}; "
                            f"beta_switch {st.beta_switch})")
        return self.status != "running"

    def _step_in_beta(self) -> bool:
        """:class:`~.strategy.ShrinkSteps`: a β step, 1 − β ← f (1 − β), with τ_d free; f moves
        halfway to 1 after a failure, and the march fails once f > ``min_shrink``. A pulse
        still above the target is accepted; the first past it leads to the pulse at the target
        (:meth:`_land`). Returns whether a pulse was accepted."""
        st, grid = self.strategy.steps, self.strategy.grid
        target = self.targets[0]
        while True:
            if self.beta >= self.beta_cap:
                self.status = "capped"
                self.message = (f"beta={self.beta:.6f} reached the natural steps' cap "
                                f"{self.beta_cap}")
                return False
            b_new = 1.0 - (1.0 - self.beta) * self.shrink
            sol, new = tangent_step(self.params, self.current, b_new, "beta", self._points(),
                                    self.spec, regrid=grid.regrid,
                                    corrector=self.strategy.corrector)
            ok = sol.stats.converged
            q_new = float(sol.x[-1])
            pulse = sol.to_pulse() if ok else None
            self._tried_natural(q_new, sol, pulse, f"beta-step to {b_new:.6f}: "
                                                   f"{sol.stats.message}")
            if not ok:
                self.shrink = 1.0 - 0.5 * (1.0 - self.shrink)
                if self.shrink > st.min_shrink:
                    self.status = "failed"
                    self.message = (f"beta-steps stopped converging at beta={self.beta:.6f}: the "
                                    f"step 1-beta <- {1 - 2 * (1 - self.shrink):.4f}(1-beta), the "
                                    f"smallest allowed, failed ({sol.stats.message})")
                    return False
                continue
            self.shrink = st.shrink
            if q_new > target:
                self._accept_natural(sol, new, pulse.L, "beta")
                return True
            return self._land(sol, target)

    def _land(self, below: SteadySolution, target) -> bool:
        """The pulse at ``target`` from the first β pulse past it: a τ_d step on its grid by the
        ``landing`` corrector; if that fails, the pair that brackets the target (the current
        pulse above it, ``below``) interpolated in τ_d and solved on a grid adapted to it.
        Returns whether it converged (then the march is "finished", else "failed")."""
        st = self.strategy.steps
        n = self._points()
        sol, new = tangent_step(self.params, PulseOnGrid.of(below, math.inf), target, "tau_d", n,
                                self.spec, regrid=math.inf, corrector=st.landing)
        pulse, ok, msg = judge_pulse(sol, self.humps)
        self._tried_natural(target, sol, pulse if ok else None, msg)
        if not ok:
            sol = solve_between(self.params, self.current, below, target, n, self.spec,
                                max_iter=st.landing.max_iter)
            pulse, ok, msg = judge_pulse(sol, self.humps)
            self._tried_natural(target, sol, pulse if ok else None, msg)
            new = PulseOnGrid.of(sol, pulse.L)
        if not ok:
            self.status = "failed"
            self.message = (f"the solve at the target tau_d/tau_min={target:.4f} from the two "
                            f"bracketing beta-step pulses failed ({msg})")
            return False
        self._accept_natural(sol, new, pulse.L, "tau_d")
        self.targets.pop(0)
        self.status, self.message = "finished", f"reached tau_d/tau_min={target:.6f}"
        return True

    def _accept_natural(self, sol, new: PulseOnGrid, L, method):
        self.sol, self._method = sol, method
        self._set_current(new, L)

    def _hand(self, sol, extra):
        """Hand ``sol`` to ``on_accept`` with the driver's attributes."""
        self._last_written_L = self.L
        if self.on_accept is None:
            return None
        res = self.on_accept(sol, {**self.state_attrs(), **extra})
        self.n_written += 1
        return res

    def _told(self, q, new, msg):
        if self.on_attempt:
            self.on_attempt(float(new.x[-1]) if new is not None else q,
                            new.to_pulse() if new is not None else None, msg)
        if self.log:
            self.log(f"at tau_d/tau_min={q:.7f} (L={self.L:.1f} m): {msg}")

    # ---------------------------------------------------------------- grid policy extras
    def _relay(self) -> bool:
        """The stretched grid's fallback where the corrector failed at ds_min: the current pulse
        with its healing front's steep cells split (:func:`~.relay.refine_front`), handed to
        ``on_accept`` (``relaid`` and its change at fixed τ_d as attributes); if it passes, the
        march restarts from it with ds = 2 ds_min. Returns whether the march goes on."""
        g = self.strategy.grid
        if not (self.strategy.stretch and self.n_relays < g.relay
                and self._relaid_at != self.n_steps):
            return False
        if self._collect():
            return True                    # a check refined the grid: on from its pulse
        self.n_relays += 1
        self._relaid_at = self.n_steps
        q = float(self.sol.x[-1])
        new, dbeta, dL_rel, msg = refine_front(self.params, self.sol, levels=g.relay_levels)
        self._told(q, new, f"corrector stalled; {msg}")
        if new is None:
            self.message += f"; then {msg}"
            return False
        res = self._hand(new, {"relaid": True, "relay_dbeta": float(dbeta),
                               "relay_dL_rel": float(dL_rel)})
        if hasattr(res, "discard"):
            res = res.result()
        if res is not None and not res.passed:
            self.message += (f"; then {msg}, but the refined pulse failed its grid check "
                             f"({res.message})")
            return False
        self.restart(res.sol if res is not None else new, 2.0 * self.strategy.steps.ds_min)
        self._last_written_L = self.L
        return True

    def recentre_front(self) -> bool:
        """Where the finest cells of the healing-front zone lie more than ``recentre`` · L from
        its steep drop, move the zone back onto it and go on from the re-solved pulse
        (:func:`~.relay.recentre`). A re-solve that does not converge, or that moves β or L at
        fixed τ_d by more than :data:`~.tolerance.RESOLVE_CHANGE` times the grid tolerance (it
        found another solution), leaves the march as it was. Returns whether the grid moved."""
        g = self.strategy.grid
        if not (self.strategy.stretch and g.recentre > 0 and self.status == "running"):
            return False
        try:
            offset = zone_offset(self.params, self.sol, g.back_zone)
        except ValueError:
            return False
        if not abs(offset[0]) > g.recentre * self.L:
            return False
        new, dbeta, dL_rel, _, msg = recentre(self.params, self.sol, g.front_zone, g.back_zone,
                                              offset=offset)
        same = GridTolerance(RESOLVE_CHANGE * GRID_TOLERANCE.beta,
                             RESOLVE_CHANGE * GRID_TOLERANCE.L)
        if new is not None and not same.passes(dbeta, dL_rel):
            new, msg = None, f"{msg}: refused, more than {RESOLVE_CHANGE:g} x the grid tolerance"
        self._told(float(self.sol.x[-1]), new, msg)
        if new is None:
            return False
        self.n_recentred += 1
        self.replace(new)
        return True

    # ---------------------------------------------------------------- one accepted pulse
    def _krylov(self) -> bool:
        """Whether the corrector of the next step solves on an earlier LU (KrylovLU)."""
        return isinstance(self.strategy.corrector_for(self.held).linear, KrylovLU)

    def _forget(self, keep_lu=False):
        """Drop what was kept of the last corrector (the pulse changed grid or was replaced);
        ``keep_lu``: keep its LU, of a nearby pulse on a nearby grid, for the Krylov solves of
        the next tangent and corrector (they test their own residual; a size that no longer
        fits is never used)."""
        self._jac = self._arc = self._n = self._sign = None
        if not keep_lu:
            self._lu = None

    def _tangent(self):
        """The unit family tangent at the current pulse (:func:`family_tangent`), once per pulse;
        by refinement with the last corrector's LU where the corrector keeps it
        (:func:`tangent_by_refinement`), oriented along the previous tangent."""
        if self._n is not None:
            return self._n
        base, x, n = self._base, self._x, None
        if self._lu is not None and self._lu[0].shape[0] == x.size:
            if self._jac is not None:
                A = self._jac
            elif self._arc is not None:
                A = self._arc.residual_and_jacobian(x)[1]
            else:                 # the pulse was replaced: [J; c] with c the orientation
                A = tangent_matrix(base, x, self._orient)
            n = tangent_by_refinement(A, self._lu)
            if n is not None:
                c_b, c_q, _ = self._orient
                n = unit_tangent(n if c_b * n[-2] + c_q * n[-1] >= 0 else -n, self.beta,
                                 self.kappa)
        self._jac = None
        if n is None:
            n = family_tangent(base, x, self._orient)
        self._n = n
        return n

    def _predict(self, n, ds):
        """The predicted grid, ln v, pin, Hilbert matrix, β and q of a step of ``ds`` along the
        unit tangent ``n`` (stages as named in the comments)."""
        P, S, base, x = self.params, self.strategy, self._base, self._x
        t_a, t_Q = -n[-2] / (1.0 - self.beta), n[-1] / self.kappa
        # d ln L/ds along the tangent, by a finite difference of the FWHM
        eps = 1e-4
        dlnL = (math.log(pulse_length(base.xi, np.exp(x[:-2] + eps * n[:-2]), P.v_star,
                                      crossings=False)) - math.log(self.L)) / eps
        bp = 1.0 - (1.0 - self.beta) * math.exp(ds * t_a)
        qp = self.q + ds * self.kappa * t_Q
        P.check_tau_d(qp * P.tau_min)
        if S.stretch:
            g = S.grid
            # deform the grid with the pulse, nodal ln v kept: the healing-front zone moved by
            # the predicted change of L (the tangent's, or the last step's dL/ds)
            x_pin = base.xi[base.pin_index]
            x_left = pulse_length(base.xi, np.exp(x[:-2]), P.v_star)[1]
            has_secant = self._prev is not None and self._prev[0].size == x.size
            mode = S.predictor.mode(ds, self._rate is not None, has_secant)
            shift = ds * self._rate if mode != "tangent" else math.expm1(ds * dlnL) * self.L
            xn = stretch_grid(base.xi, x_pin, shift, g.front_zone * self.L, x_left,
                              g.back_zone * self.L)
            yn, k, ky, H = x[:-2].copy(), base.pin_index, base.y_pin, None
            if mode == "secant":
                # ln v node by node along the secant through the last two pulses
                x_prev, ds_prev = self._prev
                ys = x[:-2] + (ds / ds_prev) * (x[:-2] - x_prev[:-2])
                if np.all(np.isfinite(ys)):
                    yn = ys
                else:
                    mode = "length"
            self.last_predictor = mode
            return xn, yn, k, ky, H, bp, qp, base.n
        # ln v stretched behind the leading edge by exp(ds · d ln L/ds): the healing edge moves
        # by many of its own widths per step, which the linear tangent in ln v cannot carry
        self.last_predictor = "tangent"
        yp = stretch_profile(base.xi, x[:-2], base.xi[base.pin_index], math.exp(ds * dlnL))
        n_cur = self.n_points
        if n_cur == base.n and abs(self.L / self._L_grid - 1.0) < S.grid.regrid:
            return base.xi, yp, base.pin_index, base.y_pin, base.H, bp, qp, n_cur
        xn, yn = regrid_guess(P, qp, base.xi, yp, bp, n_cur, self.spec)
        k, _ = front_pin(xn, yn, math.log(P.v_stick(qp * P.tau_min)))
        return xn, yn, k, float(yn[k]), None, bp, qp, n_cur

    def _attempt(self):
        """One predictor–corrector attempt at the current ds: (ok, solution or None, message,
        (t_a, t_Q), predicted q)."""
        S = self.strategy
        n = self._tangent()
        t_a, t_Q = -n[-2] / (1.0 - self.beta), n[-1] / self.kappa
        self._orient = (n[-2], n[-1], self.kappa)
        self.ds = ds = self._toward_stop(self.ds, t_Q)
        new, its, n_cur = None, 0, self._base.n
        qp = self.q + ds * self.kappa * t_Q
        bp = math.nan
        try:
            # predict
            xn, yn, k, ky, H, bp, qp, n_cur = self._predict(n, ds)
        except (RuntimeError, ValueError) as exc:
            ok, msg = False, f"predictor unusable: {exc}"
        else:
            # correct: the steady equations closed by the arclength condition
            nb = SteadyProblem(self.params, qp, xn, k, ky, free="both", H=H)
            arc = ArclengthProblem(nb, math.log(1.0 - self.beta), self.q, t_a, t_Q, self.kappa,
                                   ds)
            x0 = np.concatenate([yn, [bp, qp]])
            corr = S.corrector_for(self.held)
            lu = self._lu if self._lu is not None and self._lu[0].shape[0] == x0.size else None
            # the held corrector's creep stop acts near the cap only (after halvings below it,
            # the free corrector's)
            near_cap = ds >= min(getattr(S.steps, "cap_shrink", 1.0), 1.0) * self.cap * (1 - 1e-9)
            creep = corr.creep if (not self.held or near_cap) else S.corrector.creep
            t0 = time.perf_counter()
            xs, st = corr.solve(arc, x0, lu=lu, creep=creep)
            new = SteadySolution(nb, xs, st, time.perf_counter() - t0, 1)
            self._candidate = (st.lu, st.jacobian, arc)
            st.lu = st.jacobian = None
            ok, msg, its = st.converged, st.message, st.iterations
            self.n_iterations += its
            if ok and not judge_pulse(new, self.humps)[1]:
                ok, msg = False, "converged to a multi-hump solution: rejected"
        msg = f"arclength step ds={ds:.3g} (N={n_cur}, {its} it.) to beta~{bp:.6f}: {msg}"
        return ok, new, msg, (t_a, t_Q), qp

    def _guard(self, new, msg):
        """The strategy's :class:`~.strategy.SignGuard` on a converged step: (accepted, message,
        the sign at ``new``, None without a guard).
        The sign of det of the corrector's bordered matrix [J; r] at ``new`` (r the arclength
        row, from the current tangent; :func:`bordered_sign`, on the corrector's LU where
        refinement converges) against the current pulse's, where both lie on one discretisation
        (the same N, and the same grid or its deformation). The first step from a pulse whose
        sign is not known (the start, a replaced or refined pulse) only takes it."""
        g = self.strategy.guard
        if g is None:
            return True, msg, None
        lu, jac, arc = self._candidate
        if jac is None:
            jac = arc.residual_and_jacobian(new.x)[1]
        sign = bordered_sign(jac, lu)
        base = self._base
        same = new.problem.n == base.n and (self.strategy.stretch or new.problem.xi is base.xi)
        verdict = g.judge(self._sign if same else None, sign, self.ds)
        if verdict == "keep":
            return True, msg, sign
        change = f"sign det [J; r] {self._sign:+d} -> {sign:+d}"
        if verdict == "retake":
            return False, (f"{msg}; refused by the sign guard: {change} (the step left the "
                           "branch: past a fold's tip or onto another branch)"), None
        self.sign_changes.append(float(new.x[-1]))
        if self.log:
            self.log(f"sign guard: {change} persists at ds={self.ds:.3g} < 2 x floor: a branch "
                     f"point crossed near tau_d/tau_min={float(new.x[-1]):.6f}")
        return True, f"{msg}; {change} at ds < 2 x floor: a branch point crossed", sign

    def _step_failed(self, st, pred_ds_max):
        """What a corrector's failure teaches the step control: a tangent step above the
        predictor's ds_max failed; with held steps, a failure at or near the cap lowers it."""
        if self.last_predictor == "tangent" and self.ds > pred_ds_max:
            self._tangent_failed = True
        if self.held and st.cap_shrink < 1.0 and self.ds >= st.cap_shrink * self.cap:
            self.cap = max(st.cap_shrink * min(self.ds, self.cap), st.ds_min)
            self._at_cap = 0

    def _toward_stop(self, ds, t_Q):
        """``ds``, shortened where the predicted τ_d would pass ``stop`` by more than the step
        control's ``overshoot`` times the distance left (to ds_min at least)."""
        st = self.strategy.steps
        left = self.direction * (self.stop - self.q)
        rate = self.direction * self.kappa * t_Q          # > 0: moving toward stop
        reach = (1.0 + st.overshoot) * left
        if not (math.isfinite(reach) and left > 0 and rate > 0 and ds * rate > reach):
            return ds
        return max(reach / rate, st.ds_min)

    def advance(self):
        """One accepted pulse (halving ds on failure). Returns None, or the message when ds fell
        below ds_min (status "failed")."""
        S = self.strategy
        st, pred_ds_max = S.steps, getattr(S.predictor, "ds_max", math.inf)
        while True:
            ok, new, msg, tangent, qp = self._attempt()
            self.n_attempts += 1
            jumped, sign = False, None
            if ok:
                ok, msg, sign = self._guard(new, msg)
                jumped = not ok
            self.message = msg
            if self.on_attempt:
                qa = float(new.x[-1]) if new is not None else qp
                self.on_attempt(qa, new.to_pulse() if ok else None, msg)
            if ok:
                break
            self.n_failed += 1
            if not jumped:                 # a step that left the branch only halves ds
                self._step_failed(st, pred_ds_max)
            self.ds *= 0.5
            if self.ds < st.ds_min:
                self.status = "failed"
                self.message = (f"arclength steps stopped converging at beta={self.beta:.6f}, "
                                f"tau_d/tau_min={self.q:.6f}: ds fell below {st.ds_min} ({msg})")
                return self.message
        if new.problem.xi is not self._base.xi:
            self._L_grid = new.to_pulse().L
        self._lu, self._jac, self._arc = (self._candidate if S.corrector.reuse_lu
                                          else (None, None, None))
        self._n, self._sign = None, sign   # the guard's sign at the new pulse
        # the history: a nodal secant only across a step that kept the front on its nodes
        lineage = (S.stretch and new.problem.n == self._base.n
                   and self.last_predictor in ("length", "secant"))
        self._prev = (self._x, self.ds) if lineage else None
        L_old = self.L
        self._accept(new)
        self._rate = (self.L - L_old) / self.ds
        if S.held and self._tangent_failed and self.last_predictor in ("length", "secant"):
            self.held = True
        self._tangent_failed = False
        if self.held and st.cap_shrink < 1.0 and self.ds >= self.cap * (1.0 - 1e-9):
            self._at_cap += 1
            if self._at_cap >= st.cap_grow_after:
                self.cap = min(self.cap / st.cap_shrink, pred_ds_max)
                self._at_cap = 0
        ds_max = min(st.ds_max, self.cap) if self.held else st.ds_max
        self.ds = st.next_ds(self.ds, new.stats.iterations, ds_max)
        self.tangent = tangent
        if self.direction * tangent[1] < 0 and self.fold is None:
            self.fold = self.q
        self.n_steps += 1
        self._update_status()
        return None

    def _accept(self, sol):
        self.sol, self._base, self._x = sol, sol.problem, sol.x.copy()
        self.beta, self.q = float(self._x[-2]), float(self._x[-1])
        self.L = sol.to_pulse().L

    def _update_status(self):
        if self.direction * (self.q - self.stop) >= -1e-12:
            self.status = "finished"
            self.message = (f"reached tau_d/tau_min={self.q:.6f} "
                            f"{'>=' if self.direction > 0 else '<='} {self.stop}")
        elif self.L >= self.max_length:
            self.status = "stopped"
            self.message = f"pulse length L={self.L:.5g} m reached max_length={self.max_length:g} m"
        elif (math.isfinite(self.stop) and self.fold is not None
              and self.direction * self.tangent[1] < 0
              and self.direction * (self.q - self.q_start) <= 0):
            # the branch turned away from stop at a fold: it cannot reach stop; its other side
            # is followed back to the start's τ_d
            self.status = "stopped"
            self.message = (f"the branch folds at tau_d/tau_min={self.fold:.6f} before "
                            f"{self.stop}: traced back past the start's {self.q_start:.6f} on "
                            f"its other side")

    def replace(self, sol: SteadySolution) -> None:
        """Continue from ``sol`` (x = (y, β, q); e.g. the refined pulse of a grid check) instead of
        the current pulse: its grid becomes the march's (the nodal secant starts afresh; dL/ds of
        the last step is kept; a Krylov corrector keeps the last LU as its preconditioner)."""
        self._prev = None
        self._forget(keep_lu=self._krylov())
        self._accept(sol)
        self._L_grid = self.L
        if self.status in ("finished", "stopped"):
            self.status = "running"
            self._update_status()

    def restart(self, sol: SteadySolution, ds: float) -> None:
        """Continue (a failed march too) from ``sol`` (x = (y, β, q)) with the step ``ds``: its
        grid becomes the march's, the status "running" (or "finished"/"stopped" if ``sol`` is
        already there); the tangent's orientation, κ and dL/ds of the last step are kept (and,
        with a Krylov corrector, the last LU as its preconditioner)."""
        self._prev = None
        self._forget(keep_lu=self._krylov())
        self._accept(sol)
        self._L_grid = self.L
        self.ds = float(ds)
        self.status, self.message = "running", ""
        self._update_status()
