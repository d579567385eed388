"""spectrum: the linear stability spectrum of a steady pulse — the operator M(σ) and its kernels,
the eigensolve, the error ladder (refine), the unstable-eigenvalue count, the store, the driver along
a family, and the power-law fits of the rates. Built on the steady solution only; the time-domain
studies (:mod:`slippulse.timedomain`) sit above it."""
from .pulse import PulseSpectrum, pulse_spectrum
from .family import run_spectrum
from .refine import RefinedRate, refine_leading
from .count import count_unstable

__all__ = ['PulseSpectrum', 'pulse_spectrum', 'run_spectrum', 'RefinedRate', 'refine_leading',
           'count_unstable']
