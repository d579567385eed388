"""steady: steady pulses — the spline Hilbert transform, adapted grids, the residual and its exact
Jacobian, Newton, the solver, continuation of the family, its analysis and the mode-II map."""
from .equations import SteadyProblem, integrate_state
from .solver import GridSpec, SteadySolution, solve_on_grid, solve_pulse
from .continuation import AUTO, Continuation, FamilyReport, FamilyRun, Strategy, run_family
from .analysis import analyse_family, analyse_pulse
from .fits import divergence_fit
from .measures import pulse_length

__all__ = ['SteadyProblem', 'integrate_state', 'GridSpec', 'SteadySolution', 'solve_on_grid',
           'solve_pulse', 'AUTO', 'Continuation', 'FamilyReport', 'FamilyRun', 'Strategy',
           'run_family',
           'analyse_family', 'analyse_pulse', 'divergence_fit', 'pulse_length']
