"""Real FFTs for the SBI code: pyfftw plans made once per size, wisdom cached; numpy.fft fallback.

Conventions (those of numpy.fft.rfft): for a real array u_j, j = 0..N−1, on a periodic domain of
length λ with x_j = j λ/N,

    û_k = Σ_j u_j e^{−2πi jk/N},   k = 0..N/2,       u_j = (1/N) Σ_k û_k e^{+2πi jk/N}  (Hermitian),

so that the wavenumber of mode k is k·2π/λ. The forward transform is unnormalised, the inverse
carries the 1/N.

Notes
-----
Plans are made with FFTW_ESTIMATE by default. ESTIMATE picks the algorithm by a deterministic
heuristic, so a resumed run performs the very same floating-point operations as the uninterrupted
one (bit-exact restarts). ``planner="measure"`` times candidate algorithms instead (slightly faster
transforms at large N); its choice is stored as FFTW wisdom in ``$XDG_CACHE_HOME/slippulse`` and
reloaded by later processes, which makes it reproducible as long as the cache is kept.
"""
from __future__ import annotations

import os
import pickle
import warnings

import numpy as np

from ..core.atomic import replacing_open

try:
    import pyfftw
    import pyfftw.builders
    HAVE_PYFFTW = True
except ImportError:  # pragma: no cover - exercised only where pyfftw is missing
    HAVE_PYFFTW = False

# the FFTW planning efforts by their [fft] planner names (dynamics.config checks the key)
PLANNERS = {"estimate": "FFTW_ESTIMATE", "measure": "FFTW_MEASURE", "patient": "FFTW_PATIENT"}
_WISDOM_LOADED = False


def wisdom_path() -> str:
    """File where FFTW wisdom is cached between processes."""
    base = os.environ.get("XDG_CACHE_HOME", os.path.join(os.path.expanduser("~"), ".cache"))
    return os.path.join(base, "slippulse", "fftw_wisdom.pkl")


def _load_wisdom() -> None:
    global _WISDOM_LOADED
    if _WISDOM_LOADED or not HAVE_PYFFTW:
        return
    _WISDOM_LOADED = True
    try:
        with open(wisdom_path(), "rb") as fh:
            pyfftw.import_wisdom(pickle.load(fh))
    except (OSError, pickle.PickleError, EOFError, ValueError, TypeError):
        pass


def _save_wisdom() -> None:
    path = wisdom_path()
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with replacing_open(path, "wb") as fh:
            pickle.dump(pyfftw.export_wisdom(), fh)
    except OSError:
        pass


class RealFFT:
    """Forward and inverse real FFT of a fixed size N, planned once.

    Parameters
    ----------
    n : int
        Transform size (number of grid points), even.
    threads : int
        FFTW threads (ignored by the numpy fallback).
    planner : {"estimate", "measure", "patient"}
        FFTW planner effort; see the module notes on reproducibility.
    backend : {"auto", "pyfftw", "numpy"}
        "auto" uses pyfftw when importable and warns when it falls back to numpy.fft.

    Notes
    -----
    ``forward`` and ``inverse`` return *views of internal buffers* that the next call overwrites;
    copy them if they must survive another transform.
    """

    def __init__(self, n: int, threads: int = 1, planner: str = "estimate", backend: str = "auto"):
        if n < 2 or n % 2:
            raise ValueError(f"FFT size n={n} must be an even integer >= 2")
        if planner not in PLANNERS:
            raise ValueError(f"planner={planner!r} must be one of {sorted(PLANNERS)}")
        if backend not in ("auto", "pyfftw", "numpy"):
            raise ValueError(f"backend={backend!r} must be 'auto', 'pyfftw' or 'numpy'")
        self.n = int(n)
        self.nk = self.n // 2 + 1
        self.threads = int(threads)
        if backend == "pyfftw" and not HAVE_PYFFTW:
            raise ImportError("backend='pyfftw' requested but pyfftw is not installed")
        use_fftw = HAVE_PYFFTW and backend != "numpy"
        if backend == "auto" and not HAVE_PYFFTW:
            warnings.warn("pyfftw not installed: falling back to numpy.fft (slower)", RuntimeWarning)
        self.backend = "pyfftw" if use_fftw else "numpy"
        if use_fftw:
            _load_wisdom()
            effort = PLANNERS[planner]
            self._rin = pyfftw.empty_aligned(self.n, dtype="float64")
            self._cin = pyfftw.empty_aligned(self.nk, dtype="complex128")
            self._fwd = pyfftw.builders.rfft(self._rin, threads=self.threads, planner_effort=effort,
                                             overwrite_input=True, avoid_copy=True)
            self._inv = pyfftw.builders.irfft(self._cin, n=self.n, threads=self.threads,
                                              planner_effort=effort, overwrite_input=True,
                                              avoid_copy=True)
            if planner != "estimate":
                _save_wisdom()

    def forward(self, u: np.ndarray) -> np.ndarray:
        """û = rfft(u), length N/2+1 (unnormalised)."""
        if self.backend == "numpy":
            return np.fft.rfft(u)
        self._rin[:] = u
        return self._fwd()

    def inverse(self, uk: np.ndarray) -> np.ndarray:
        """u = irfft(û), length N (carries the 1/N)."""
        if self.backend == "numpy":
            return np.fft.irfft(uk, n=self.n)
        self._cin[:] = uk
        return self._inv()
