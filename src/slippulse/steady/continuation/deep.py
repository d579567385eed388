"""The deep continuation as an object: :class:`DeepMarch`, a pseudo-arclength march toward β → 1
with its state, status and counters on the solver (in the style of scipy's ``OdeSolver``:
``step()`` advances by one accepted pulse, ``status`` says whether it may go on).
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..measures import pulse_length
from ..equations import SteadyProblem
from ..newton import SolveStats, newton
from ..solver import GridSpec, SteadySolution, front_pin, regrid_guess
from .arclength import (ArclengthProblem, DeepSettings, family_tangent, tangent_by_refinement,
                        unit_tangent)
from .natural import _judge
from .stretch import _stretch, stretch_grid


class DeepMarch:
    """Pseudo-arclength continuation of the family in (a, q/κ), a = ln(1 − β), q = τ_d/τ_min.

    Parameters
    ----------
    params : Parameters
    start : SteadySolution of ``free="both"`` (x = (y, β, q)), or a tuple (xi, y, β, q) (the pin
        is then put at the leading edge, :func:`front_pin`).
    n_points : grid points of re-laid grids (ignored with ``settings.stretch``, where the grid is
        the start's, deformed every step); default: the start grid's.
    spec : layout of re-laid grids.
    settings : :class:`DeepSettings` (steps, Newton iterations, stretch).
    stop : the march is ``"finished"`` once τ_d/τ_min ≤ stop (default: never).
    max_length : the march is ``"stopped"`` once L ≥ max_length (m; default ``settings.max_length``).
    on_attempt : callable(tau_d_ratio, pulse_or_None, message), optional; called after every
        attempt.
    n_of : callable() → N, optional; the current N for re-laid grids (a grid check may raise it).

    Attributes
    ----------
    status : "running", "finished" (stop reached), "stopped" (max_length), "failed" (ds fell below
        ``ds_min``; ``message`` says where and why).
    sol : SteadySolution — the current pulse (x = (y, β, q)).
    q, beta, L : its τ_d/τ_min, β and length (m).
    ds : the next arclength step.
    tangent : (t_a, t_Q) — the unit tangent used for the last accepted step.
    fold : τ_d/τ_min where τ_d first rose along the march (t_Q > 0), or None.
    n_steps, n_attempts, n_failed, n_iterations : accepted steps, attempts, failed attempts,
        Newton iterations (all attempts).
    held : ``settings.hold`` has capped ds at ``cap`` (which see).
    cap : the largest ds once held: ``settings.predictor_ds_max``, lowered by
        ``settings.cap_shrink`` × the failed ds after every failed attempt within that factor of
        it, raised by 1/``cap_shrink`` (up to ``predictor_ds_max``) after
        ``settings.cap_grow_after`` accepted steps at it in a row.
    message : the last attempt's message (the reason, once failed).
    last_predictor : the predictor of the last attempt on the deformed grid: "tangent", "length"
        or "secant" (``settings.predictor``, which see; "length"/"secant" need the history they
        name and fall back to the lower order without it).

    Notes
    -----
    The predictors of ``settings.stretch`` (issue 18, measured from the 7187 m pulse, N = 4370):
    with "tangent" the grid's front zone is moved by the change of L the family tangent predicts,
    which falls ≈ 13 % short of the change the corrector then finds (2.97 m against 3.42 m per
    step of ds = 0.0002): every step the healing front lands ≈ 0.45 m (about one cell) off its
    nodes, ln v changes by ≈ 0.7 at the nodes of its steep drop, and the damped Newton creeps
    (15 iterations a step). "length" moves it by the change of L per ds of the last accepted step
    (3 iterations); "secant" also predicts ln v node by node along the secant through the last two
    pulses of the same deformed grid (starting residual 8e−8 instead of 5e−5; 2–3 iterations).
    """

    def __init__(self, params, start, n_points=None, spec=GridSpec(), settings=DeepSettings(),
                 stop=-math.inf, max_length=None, on_attempt=None, n_of=None):
        self.params, self.spec, self.settings = params, spec, settings
        if settings.predictor not in ("tangent", "length", "secant"):
            raise ValueError(f"predictor={settings.predictor!r} is invalid: must be 'tangent', "
                             f"'length' or 'secant'")
        self.stop = stop
        self.max_length = settings.max_length if max_length is None else max_length
        self.on_attempt = on_attempt
        if isinstance(start, SteadySolution):
            base, x = start.problem, np.asarray(start.x, float).copy()
        else:
            xi, y, beta, q = start
            k, _ = front_pin(xi, y, math.log(params.v_stick(q * params.tau_min)))
            base = SteadyProblem(params, q, xi, k, float(y[k]), free="both")
            x = np.concatenate([y, [beta, q]])
        self.n_points = base.n if n_points is None else n_points
        self._n_of = n_of
        self._base, self._x = base, x
        self.beta, self.q = float(x[-2]), float(x[-1])
        # κ: |dq/da| at the start, so that one unit of ds moves a and q/κ alike
        n0 = family_tangent(base, x, (1.0, 0.0, 1.0))
        self.kappa = max(abs(n0[-1] / (-n0[-2] / (1.0 - self.beta))), 1e-5)
        self._orient = (1.0, 0.0, self.kappa)
        self.ds = settings.ds
        self.L = self._L_grid = pulse_length(base.xi, np.exp(x[:-2]), params.v_star,
                                             crossings=False)
        self.sol = SteadySolution(base, x, SolveStats(True, "start", 0, 0.0), 0.0, 0)
        self.tangent = (math.nan, math.nan)
        self.fold = None
        self.status = "running"
        self.message = ""
        self.n_steps = self.n_attempts = self.n_failed = self.n_iterations = 0
        self.last_predictor = "tangent"
        # the history of the "length" and "secant" predictors: dL/ds of the last accepted step
        # (kept by replace/restart: those re-solve the same pulse on another grid); (x, ds) of the
        # pulse before the current one and the step from it, kept only while the current grid is
        # that pulse's deformed (same nodes, each on the same feature) by a "length" step
        self._rate = None
        self._prev = None
        # reuse (settings.reuse_lu, settings.chord): the LU the last accepted corrector factored,
        # the Jacobian at its pulse (None when chord iterations converged it), its arclength
        # problem, and the tangent at the current pulse once computed
        self._forget()
        self._candidate = (None, None, None)
        # settings.hold: a tangent step above predictor_ds_max failed since the last accepted
        # step; held: ds capped at predictor_ds_max from then on
        self._tangent_failed = False
        self.held = False
        self.cap = settings.predictor_ds_max
        self._at_cap = 0

    def _forget(self):
        """Drop what was kept of the last corrector (the pulse changed grid or was replaced)."""
        self._lu = self._jac = self._arc = self._n = None

    def _tangent(self):
        """The unit family tangent at the current pulse (:func:`family_tangent`), once per pulse;
        with ``settings.reuse_lu`` by refinement with the last corrector's LU
        (:func:`tangent_by_refinement`), oriented along the previous tangent."""
        if self._n is not None:
            return self._n
        base, x, n = self._base, self._x, None
        if self._lu is not None and self._lu[0].shape[0] == x.size:
            A = self._jac if self._jac is not None else self._arc.residual_and_jacobian(x)[1]
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

    def resume_step(self, beta_prev, q_prev, L_prev=None):
        """Set ds to the step from the pulse before the start, (β_prev, τ_d/τ_min = q_prev), to
        the start, measured in this march's plane (ln(1−β), q/κ) and clipped to
        [ds_min, ds_max]: a march that resumes from a file goes on at the pace it had, instead
        of from ``settings.ds`` (which fails and halves several times deep in the family).
        With that pulse's length ``L_prev`` (m), its change of L per ds also seeds the "length"
        predictor (``settings.predictor``), so the first step moves the grid's front zone by it
        instead of by the tangent's. With ``settings.hold`` the first step is then at most
        ``predictor_ds_max``, where that predictor acts: the two last pulses of a file are
        usually several steps apart (``spacing``), and deep in the family the tangent's step
        from the longer distance failed at 25 iterations, once or twice, on every resume (stops
        44–45, 60–90 s each at N = 5062)."""
        s = self.settings
        da = math.log(1.0 - self.beta) - math.log(1.0 - beta_prev)
        dq = (self.q - q_prev) / self.kappa
        ds = math.hypot(da, dq)
        if math.isfinite(ds) and ds > 0:
            self.ds = min(max(ds, s.ds_min), s.ds_max)
            if L_prev is not None and math.isfinite(L_prev):
                self._rate = (self.L - L_prev) / ds
                if s.hold and s.stretch and s.predictor in ("length", "secant"):
                    self.ds = max(min(self.ds, s.predictor_ds_max), s.ds_min)
        return self.ds

    def _n_now(self):
        return self.n_points if self._n_of is None else self._n_of()

    def _attempt(self):
        """One predictor–corrector attempt at the current ds: (ok, solution or None, message,
        (t_a, t_Q))."""
        P, s, base, x = self.params, self.settings, self._base, self._x
        beta, q, ds = self.beta, self.q, self.ds
        n = self._tangent()
        t_a, t_Q = -n[-2] / (1.0 - beta), n[-1] / self.kappa
        self._orient = (n[-2], n[-1], self.kappa)
        # predict: a + ds t_a, q + ds κ t_Q; ln v by stretching the last pulse behind its leading
        # edge by exp(ds · d ln L/ds) (the healing edge moves by many of its own widths per
        # step, which the linear tangent n_y cannot carry); d ln L/ds by a finite difference
        eps = 1e-4
        dlnL = (math.log(pulse_length(base.xi, np.exp(x[:-2] + eps * n[:-2]), P.v_star,
                                      crossings=False)) -
                math.log(self.L)) / eps
        yp = _stretch(base.xi, x[:-2], base.xi[base.pin_index], math.exp(ds * dlnL))
        bp = 1.0 - (1.0 - beta) * math.exp(ds * t_a)
        qp = q + ds * self.kappa * t_Q
        n_cur = base.n if s.stretch else self._n_now()
        # keep the grid (and its Hilbert matrix) while L stays within `regrid` of the grid's L
        same = (n_cur == base.n and abs(self.L / self._L_grid - 1.0) < s.regrid)
        new = None
        try:
            P.check_tau_d(qp * P.tau_min)
            if s.stretch:
                # deform the grid with the pulse, nodal ln v kept (no interpolation)
                x_pin = base.xi[base.pin_index]
                x_left = pulse_length(base.xi, np.exp(x[:-2]), P.v_star)[1]
                shift, self.last_predictor = math.expm1(ds * dlnL) * self.L, "tangent"
                if (s.predictor in ("length", "secant") and self._rate is not None
                        and ds <= s.predictor_ds_max):
                    # the change of L per ds of the last step, where the tangent's falls short
                    shift, self.last_predictor = ds * self._rate, "length"
                xn = stretch_grid(base.xi, x_pin, shift,
                                  s.front_zone * self.L, x_left, s.back_zone * self.L)
                yn, k, ky, H = x[:-2].copy(), base.pin_index, base.y_pin, None
                if (s.predictor == "secant" and self.last_predictor == "length"
                        and self._prev is not None and self._prev[0].size == x.size):
                    # ln v node by node along the secant through the last two pulses
                    x_prev, ds_prev = self._prev
                    ys = x[:-2] + (ds / ds_prev) * (x[:-2] - x_prev[:-2])
                    if np.all(np.isfinite(ys)):
                        yn, self.last_predictor = ys, "secant"
            elif same:
                xn, yn, H = base.xi, yp, base.H
                k, ky = base.pin_index, base.y_pin
            else:
                xn, yn = regrid_guess(P, qp, base.xi, yp, bp, n_cur, self.spec)
                k, _ = front_pin(xn, yn, math.log(P.v_stick(qp * P.tau_min)))
                H, ky = None, float(yn[k])
        except (RuntimeError, ValueError) as exc:
            ok, msg = False, f"predictor unusable: {exc}"
        else:
            nb = SteadyProblem(P, qp, xn, k, ky, free="both", H=H)
            arc = ArclengthProblem(nb, math.log(1.0 - beta), q, t_a, t_Q, self.kappa, ds)
            x0 = np.concatenate([yn, [bp, qp]])
            chord = s.chord or (s.chord_held and self.held)
            lu = (self._lu if chord and self._lu is not None
                  and self._lu[0].shape[0] == x0.size else None)
            t0 = time.perf_counter()
            # creep_held: only near the cap, where the held steps' failures were; below it (after
            # halvings) the corrector gets max_iter. natural_held: the natural line search once
            # held (stop 47: after a resume, 0.00064 and 0.00032 failed after 25 iterations of
            # the ‖r‖₂ test at λ ≤ 1/4; natural converged the same corrector in 9)
            near_cap = ds >= min(s.cap_shrink, 1.0) * self.cap * (1.0 - 1e-9)
            creep = s.creep or (s.creep_held if self.held and near_cap else 0)
            search = "natural" if s.natural_held and self.held else s.line_search
            xs, st = newton(arc, x0, tol=1e-13, max_iter=s.max_iter, lu=lu, keep=s.reuse_lu,
                            creep=creep, line_search=search)
            new = SteadySolution(nb, xs, st, time.perf_counter() - t0, 1)
            self._candidate = (st.lu, st.jacobian, arc)
            st.lu = st.jacobian = None
            ok, msg = st.converged, st.message
            self.n_iterations += st.iterations
            if ok and not _judge(new)[1]:
                ok, msg = False, "converged to a multi-hump solution: rejected"
        its = new.stats.iterations if new is not None else 0
        msg = f"arclength step ds={ds:.3g} (N={n_cur}, {its} it.) to beta~{bp:.6f}: {msg}"
        return ok, new, msg, (t_a, t_Q), qp

    def step(self):
        """Advance by one accepted pulse (halving ds on failure). Returns None, or the message
        when the march failed. Raises RuntimeError when the march is not running."""
        if self.status != "running":
            raise RuntimeError(f"DeepMarch.step() with status {self.status!r}")
        s = self.settings
        while True:
            ok, new, msg, tangent, qp = self._attempt()
            self.n_attempts += 1
            self.message = msg
            if self.on_attempt:
                qa = float(new.x[-1]) if new is not None else qp
                self.on_attempt(qa, new.to_pulse() if ok else None, msg)
            if ok:
                break
            self.n_failed += 1
            if self.last_predictor == "tangent" and self.ds > s.predictor_ds_max:
                self._tangent_failed = True
            if self.held and s.cap_shrink < 1.0 and self.ds >= s.cap_shrink * self.cap:
                # a failure at or near the cap: the cap below it (settings.cap_shrink)
                self.cap = max(s.cap_shrink * min(self.ds, self.cap), s.ds_min)
                self._at_cap = 0
            self.ds *= 0.5
            if self.ds < s.ds_min:
                self.status = "failed"
                self.message = (f"arclength steps stopped converging at beta={self.beta:.6f}, "
                                f"tau_d/tau_min={self.q:.6f}: ds fell below {s.ds_min} ({msg})")
                return self.message
        if new.problem.xi is not self._base.xi:
            self._L_grid = new.to_pulse().L
        self._lu, self._jac, self._arc = self._candidate if s.reuse_lu else (None, None, None)
        self._n = None
        # the history: a nodal secant only across a step that kept the front on its nodes
        lineage = (s.stretch and new.problem.n == self._base.n
                   and self.last_predictor in ("length", "secant"))
        self._prev = (self._x, self.ds) if lineage else None
        L_old = self.L
        self._accept(new)
        self._rate = (self.L - L_old) / self.ds
        if (s.hold and s.stretch and self._tangent_failed
                and self.last_predictor in ("length", "secant")):
            self.held = True
        self._tangent_failed = False
        if self.held and s.cap_shrink < 1.0 and self.ds >= self.cap * (1.0 - 1e-9):
            self._at_cap += 1
            if self._at_cap >= s.cap_grow_after:
                self.cap = min(self.cap / s.cap_shrink, s.predictor_ds_max)
                self._at_cap = 0
        ds_max = min(s.ds_max, self.cap) if self.held else s.ds_max
        if new.stats.iterations <= 6:
            self.ds = min(1.5 * self.ds, ds_max)
        elif new.stats.iterations > 10:
            self.ds = max(0.7 * self.ds, s.ds_min)
        self.tangent = tangent
        if tangent[1] > 0 and self.fold is None:
            self.fold = self.q
        self.n_steps += 1
        self._update_status()
        return None

    def _accept(self, sol):
        self.sol, self._base, self._x = sol, sol.problem, sol.x.copy()
        self.beta, self.q = float(self._x[-2]), float(self._x[-1])
        self.L = sol.to_pulse().L

    def _update_status(self):
        if self.q <= self.stop + 1e-12:
            self.status = "finished"
            self.message = f"reached tau_d/tau_min={self.q:.6f} <= {self.stop}"
        elif self.L >= self.max_length:
            self.status = "stopped"
            self.message = f"pulse length L={self.L:.5g} m reached max_length={self.max_length:g} m"

    def replace(self, sol: SteadySolution) -> None:
        """Continue from ``sol`` (x = (y, β, q); e.g. the refined pulse of a grid check) instead of
        the current pulse: its grid becomes the march's (the nodal secant starts afresh; dL/ds of
        the last step is kept)."""
        self._prev = None
        self._forget()
        self._accept(sol)
        self._L_grid = self.L
        if self.status in ("finished", "stopped"):
            self.status = "running"
            self._update_status()

    def restart(self, sol: SteadySolution, ds: float) -> None:
        """Continue a march that failed (or any other) from ``sol`` (x = (y, β, q), e.g. the pulse
        re-laid on a new grid where the corrector stalled, :func:`~.relay.relay_pulse`) with the
        step ``ds``: its grid becomes the march's, the status "running" (or "finished"/"stopped"
        if ``sol`` is already there), the orientation of the tangent and κ kept, and dL/ds of the
        last step (the nodal secant starts afresh)."""
        self._prev = None
        self._forget()
        self._accept(sol)
        self._L_grid = self.L
        self.ds = float(ds)
        self.status, self.message = "running", ""
        self._update_status()


def march_arclength(params, start, n_points, spec=GridSpec(), deep=DeepSettings(), progress=None,
                    rep=None, why=None, n_of=None, handoff=None):
    """Pseudo-arclength continuation from `start` = (xi, y, beta, q) toward β → 1, as a generator
    over :class:`DeepMarch` (which see).

    Yields converged (solution, tangent-unit (t_a, t_Q)) pairs with ``solution.x = (y, β, q)``.
    Every attempt is counted in `rep` (a :class:`FamilyReport`) and shown by `progress`; when the
    march gives up, ``why["reason"]`` says where and why. `handoff` (a dict), when given, lets the
    caller replace the march's current pulse between steps: a solution put in
    ``handoff["sol"]`` (x = (y, β, q)) becomes the base of the next step, grid included.
    """
    def on_attempt(tau_d_ratio, pulse, msg):
        if rep is not None:
            rep.record(tau_d_ratio, pulse is not None, msg)
        if progress:
            progress(tau_d_ratio, pulse, msg)

    m = DeepMarch(params, start, n_points, spec, deep, max_length=math.inf, on_attempt=on_attempt,
                  n_of=n_of)
    while True:
        if m.step() is not None:
            if why is not None:
                why["reason"] = m.message
            return
        yield m.sol, m.tangent
        if handoff is not None and handoff.get("sol") is not None:
            m.replace(handoff.pop("sol"))
