"""Continuation of the pulse family in τ_d, one module per concept.

* :mod:`.tolerance` — the tolerances, in one place (grid criterion, Newton tolerance);
* :mod:`.strategy` — the driver's strategies (predictor, corrector, step control, grid policy,
  grid check) and their combinations :class:`Strategy`: the deep :data:`AUTO`, the shallow
  :data:`NATURAL` (τ_d steps) and :data:`BETA_STEPS`, and :data:`FROM_PULSE` or :data:`BRANCH`;
* :mod:`.driver` — :class:`Continuation`, the driver (``step()``, status, counters,
  ``on_accept``) of natural and pseudo-arclength steps alike;
* :mod:`.natural` — the natural steps' maths (tangent predictor at fixed τ_d or β, the solve
  between two pulses that bracket a target);
* :mod:`.arclength` — the arclength-closed problem and the family tangent;
* :mod:`.stretch` — the stretched predictor and the grid deformed with the pulse;
* :mod:`.homotopy` — the residual homotopy for hard re-solves;
* :mod:`.gridcheck` — grid checks (nested 2N − 1, one region refined) and the per-pulse check;
* :mod:`.relay` — the healing front refined or recentred on the deformed grid;
* :mod:`.family` — :func:`run_family`: the whole family (or the march from a stored pulse) into
  one HDF5 file, resumable.
"""
from .arclength import ArclengthProblem, family_tangent
from .driver import Accepted, Continuation
from .family import FamilyRun, from_pulse_strategy, run_family
from .gridcheck import as_both, check_grid_2n, grid_change
from .homotopy import solve_robust
from .natural import PulseOnGrid, judge_pulse, round_targets, solve_at_beta, tangent_step
from .report import FamilyReport
from .strategy import (AUTO, BETA_STEPS, BRANCH, FAMILY_POINTS, FAMILY_POINTS_BETA, FROM_PULSE, NATURAL,
                       REGRID, STRATEGIES, AdaptGrid, FreeSteps, HeldSteps, LengthPredictor,
                       NaturalPredictor, NestedCheck, NewtonCorrector, SecantPredictor, ShrinkSteps, SignGuard, Strategy,
                       StrategyError, StretchGrid, TangentPredictor, TargetSteps)
from .stretch import stretch_grid, stretch_profile
from .tolerance import GRID_TOLERANCE, NEWTON_TOL, GridTolerance

__all__ = ["AUTO", "Accepted", "FamilyRun", "AdaptGrid", "ArclengthProblem", "BETA_STEPS", "Continuation",
           "BRANCH", "from_pulse_strategy", "FAMILY_POINTS", "FAMILY_POINTS_BETA", "FROM_PULSE", "FamilyReport", "FreeSteps", "GRID_TOLERANCE",
           "GridTolerance", "HeldSteps", "LengthPredictor", "NATURAL", "NEWTON_TOL",
           "NaturalPredictor", "NestedCheck", "NewtonCorrector", "PulseOnGrid", "REGRID", "STRATEGIES",
           "SecantPredictor", "ShrinkSteps", "SignGuard", "Strategy", "StrategyError", "StretchGrid", "as_both",
           "TangentPredictor", "TargetSteps", "check_grid_2n", "family_tangent", "grid_change",
           "judge_pulse", "round_targets", "run_family", "solve_at_beta", "solve_robust",
           "stretch_grid", "stretch_profile", "tangent_step"]
