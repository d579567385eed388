"""core: what every layer shares — the parameters and their checks, the rate-and-state friction law,
the HDF5 schema of the pulse files and its validating reader, the one locked and journaled way to
write a file, and the input errors."""
from .errors import UsageError
from .params import DEFAULT, ParameterError, Parameters
from .friction import RateStateFriction
from .h5io import Pulse, SchemaError, list_pulses, read_pulse, write_pulse

__all__ = ['DEFAULT', 'ParameterError', 'Parameters', 'RateStateFriction', 'Pulse', 'SchemaError',
           'list_pulses', 'read_pulse', 'write_pulse', 'UsageError']

