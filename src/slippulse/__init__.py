"""slippulse: steady self-healing slip pulses on rate-and-state frictional interfaces (mode III),
their spectral boundary-integral dynamics, and their stability.

Layers (arrows point down only): cli → plotting → stability → steady, dynamics → core.
"""
__version__ = "0.1.0"

from .core.params import Parameters, ParameterError, DEFAULT
from .core.friction import RateStateFriction

__all__ = ['Parameters', 'ParameterError', 'DEFAULT', 'RateStateFriction', '__version__']
