"""stability: steady pulses in time — seeding the SBI, verification, ±ε perturbation runs and their
growth rates, parameter scans, and the linear stability spectrum from the steady solution."""
from .seeding import DomainSpec, SeededPulse, seed_from_file, seed_pulse
from .verify import VerifyResult, verify_pulse
from .perturbation import pair_growth, run_case, run_perturbation
from .scan import load_scan, run_scan
from .spectrum import PulseSpectrum, pulse_spectrum
from .spectrum_family import run_spectrum
from .refine import RefinedRate, refine_leading
from .count import count_unstable

__all__ = ['DomainSpec', 'SeededPulse', 'seed_from_file', 'seed_pulse', 'VerifyResult',
           'verify_pulse', 'pair_growth', 'run_case', 'run_perturbation', 'load_scan', 'run_scan',
           'PulseSpectrum', 'pulse_spectrum', 'run_spectrum', 'RefinedRate', 'refine_leading',
           'count_unstable']
