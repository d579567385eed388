"""stability: steady pulses in time — seeding the SBI, verification, ±ε perturbation runs and their
growth rates, parameter scans, and the linear stability spectrum from the steady solution."""
from .seeding import DomainSpec, SeededPulse, seed_from_file, seed_pulse  # noqa: F401
from .verify import VerifyResult, verify_pulse  # noqa: F401
from .perturbation import pair_growth, run_case, run_perturbation  # noqa: F401
from .scan import load_scan, run_scan  # noqa: F401
from .spectrum import PulseSpectrum, pulse_spectrum, run_spectrum  # noqa: F401
