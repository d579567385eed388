"""Continuation of the pulse family in τ_d, one module per concept.

* :mod:`.tolerance` — the tolerances, in one place (grid criterion, Newton tolerance);
* :mod:`.strategy` — the driver's strategies (predictor, corrector, step control, grid policy,
  grid check) and their combination :class:`Strategy`, with the product's :data:`AUTO`;
* :mod:`.driver` — :class:`Continuation`, the pseudo-arclength driver (``step()``, status,
  counters, ``on_accept``);
* :mod:`.natural` — natural-parameter steps in τ_d or β (tangent predictor, chord corrector);
* :mod:`.arclength` — the arclength-closed problem and the family tangent;
* :mod:`.stretch` — the stretched predictor and the grid deformed with the pulse;
* :mod:`.homotopy` — the residual homotopy for hard re-solves;
* :mod:`.gridcheck` — grid checks (nested 2N − 1, one region refined) and the per-pulse check;
* :mod:`.relay` — the healing front refined or recentred on the deformed grid;
* :mod:`.family` — :func:`run_family`: the whole family into one HDF5 file, resumable.
"""
from .arclength import ArclengthProblem, family_tangent
from .driver import Accepted, Continuation
from .family import run_family
from .gridcheck import _as_both, check_grid_2n, grid_change
from .homotopy import solve_robust
from .natural import (FAMILY_POINTS, FAMILY_POINTS_BETA, REGRID, _Base, march_in_beta,
                      solve_at_beta, tangent_step)
from .report import FamilyReport
from .strategy import (AUTO, STRATEGIES, AdaptGrid, FreeSteps, HeldSteps, LengthPredictor,
                       NestedCheck, NewtonCorrector, SecantPredictor, Strategy, StrategyError,
                       StretchGrid, TangentPredictor)
from .stretch import stretch_grid
from .tolerance import GRID_TOLERANCE, NEWTON_TOL, GridTolerance

__all__ = ["AUTO", "Accepted", "AdaptGrid", "ArclengthProblem", "Continuation", "FAMILY_POINTS",
           "FAMILY_POINTS_BETA", "FamilyReport", "FreeSteps", "GRID_TOLERANCE", "GridTolerance",
           "HeldSteps", "LengthPredictor", "NEWTON_TOL", "NestedCheck", "NewtonCorrector", "REGRID",
           "STRATEGIES", "SecantPredictor", "Strategy", "StrategyError", "StretchGrid",
           "TangentPredictor", "check_grid_2n", "family_tangent", "grid_change", "march_in_beta",
           "run_family", "solve_at_beta", "solve_robust", "stretch_grid", "tangent_step"]
