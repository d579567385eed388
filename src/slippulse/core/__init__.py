"""core: what every layer shares — the parameters and their checks, the rate-and-state friction law,
and the HDF5 schema of the pulse files (writing, reading, format versions)."""
from .params import DEFAULT, ParameterError, Parameters  # noqa: F401
from .friction import RateStateFriction  # noqa: F401
from .h5io import Pulse, SchemaError, list_pulses, read_pulse, write_pulse  # noqa: F401
