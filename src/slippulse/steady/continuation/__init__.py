"""Continuation of the pulse family in τ_d, one module per concept.

* :mod:`.tolerance` — the grid criterion (:class:`GridTolerance`), in one place;
* :mod:`.natural` — natural-parameter steps in τ_d or β (tangent predictor, chord corrector);
* :mod:`.arclength` — pseudo-arclength in (ln(1 − β), τ_d/τ_min): problem, tangent, march;
* :mod:`.stretch` — the stretched predictor and the grid deformed with the pulse;
* :mod:`.homotopy` — the residual homotopy for hard re-solves;
* :mod:`.gridcheck` — grid checks (2N, nested 2N − 1, one region refined) and the per-pulse
  check that chooses N or a body refinement until the criterion is met;
* :mod:`.deep` — the deep continuation as an object (:class:`DeepMarch`, status, counters,
  ``step()``, in the style of scipy's OdeSolver);
* :mod:`.family` — :func:`run_family`: the whole family into one HDF5 file, resumable.
"""
from .arclength import ArclengthProblem, DeepSettings, family_tangent
from .deep import DeepMarch, march_arclength
from .family import run_family
from .gridcheck import _as_both, check_grid_2n, grid_change
from .homotopy import solve_robust
from .natural import (FAMILY_POINTS, FAMILY_POINTS_BETA, REGRID, _Base, march_in_beta,
                      solve_at_beta, tangent_step)
from .report import FamilyReport
from .stretch import stretch_grid
from .tolerance import GRID_TOLERANCE, GridTolerance

__all__ = ["ArclengthProblem", "DeepMarch", "DeepSettings", "FAMILY_POINTS", "FAMILY_POINTS_BETA",
           "FamilyReport", "GRID_TOLERANCE", "GridTolerance", "REGRID", "check_grid_2n",
           "family_tangent", "grid_change", "march_arclength", "march_in_beta", "run_family",
           "solve_at_beta", "solve_robust", "stretch_grid", "tangent_step"]
