"""timedomain: steady pulses in time — seeding the SBI with a steady pulse, verification, ±ε and
eigenmode perturbation runs with their growth rates, and parameter scans. Reads the linear spectrum
(:mod:`slippulse.spectrum`) for the eigenmode seeds; the spectrum never reads from here."""
from .seeding import DomainSpec, SeededPulse, seed_from_file, seed_pulse
from .verify import VerifyResult, verify_pulse
from .perturbation import pair_growth, run_case, run_perturbation
from .scan import load_scan, run_scan

__all__ = ['DomainSpec', 'SeededPulse', 'seed_from_file', 'seed_pulse', 'VerifyResult',
           'verify_pulse', 'pair_growth', 'run_case', 'run_perturbation', 'load_scan', 'run_scan']
