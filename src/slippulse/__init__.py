"""slippulse: steady self-healing slip pulses on rate-and-state frictional interfaces (mode III),
their spectral boundary-integral dynamics, and their stability."""
__version__ = "0.1.0"

from .params import Parameters, ParameterError, DEFAULT  # noqa: F401
from .friction import RateStateFriction  # noqa: F401
