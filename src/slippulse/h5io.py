"""Self-describing HDF5 files for steady pulses (schema of the steady-solver issue).

Layout::

    /                      attrs: slippulse_version, created
    /parameters            attrs: mu, sigma, c_s, D, b, v_star, f0, phi_star, alpha (SI) + units
    /pulses/td1.2000       datasets xi (m), v (m/s), phi (s), tau (Pa), residual (1)
                           attrs tau_d_ratio, tau_d, tau_min, beta, c_p, L, L_tilde, v_stick, v_max,
                           max_residual, converged, n_points, wall_time, mode, status, message

Every write goes to a temporary file in the same directory that replaces the target with
``os.replace`` only once complete, so an interrupted write never leaves a corrupt file.
"""
from __future__ import annotations

import datetime as _dt
import os
import shutil
import tempfile
from dataclasses import dataclass, field

import h5py
import numpy as np

from . import __version__
from .params import Parameters

PARAM_NAMES = ("mu", "sigma", "c_s", "D", "b", "v_star", "f0", "phi_star", "alpha")
DATASETS = {"xi": "m", "v": "m/s", "phi": "s", "tau": "Pa", "residual": "1"}
ATTRS = {
    "tau_d_ratio": "1", "tau_d": "Pa", "tau_min": "Pa", "beta": "1", "c_p": "m/s", "L": "m",
    "L_tilde": "1", "v_stick": "m/s", "v_max": "m/s", "max_residual": "1", "converged": "bool",
    "n_points": "1", "wall_time": "s", "mode": "str",
}


class SchemaError(ValueError):
    """A file or group that does not follow the slippulse pulse schema."""


def pulse_label(tau_d_ratio: float) -> str:
    """Group name of a pulse: 'td' + τ_d/τ_min with 4 decimals, e.g. td1.2000."""
    return f"td{tau_d_ratio:.4f}"


@dataclass
class Pulse:
    """A steady pulse on its grid. ξ ascending, the pulse travels toward +ξ (rest state at large ξ)."""

    xi: np.ndarray
    v: np.ndarray
    phi: np.ndarray
    tau: np.ndarray
    residual: np.ndarray
    tau_d_ratio: float
    tau_d: float
    tau_min: float
    beta: float
    c_p: float
    L: float
    L_tilde: float
    v_stick: float
    v_max: float
    max_residual: float
    converged: bool
    n_points: int
    wall_time: float
    mode: str = "III"
    extra: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return pulse_label(self.tau_d_ratio)


def atomic_update(path: str, fill) -> None:
    """Copy `path` (if it exists) to a temporary file, apply `fill(h5file)`, then replace `path`."""
    path = os.path.abspath(path)
    d = os.path.dirname(path)
    os.makedirs(d, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".h5", dir=d)
    os.close(fd)
    try:
        if os.path.exists(path):
            shutil.copyfile(path, tmp)
            mode = "r+"
        else:
            mode = "w"
        with h5py.File(tmp, mode) as h5:
            if mode == "w":
                h5.attrs["slippulse_version"] = __version__
                h5.attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat()
            fill(h5)
            h5.flush()
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def write_parameters(h5: h5py.File, params: Parameters) -> None:
    grp = h5.require_group("parameters")
    for name in PARAM_NAMES:
        grp.attrs[name] = float(getattr(params, name))
        grp.attrs[f"{name}_units"] = Parameters.UNITS[name]


def read_parameters(h5: h5py.File) -> Parameters:
    if "parameters" not in h5:
        raise SchemaError("file has no 'parameters' group")
    grp = h5["parameters"]
    missing = [n for n in PARAM_NAMES if n not in grp.attrs]
    if missing:
        raise SchemaError(f"'parameters' group lacks attributes {missing}")
    return Parameters(**{n: float(grp.attrs[n]) for n in PARAM_NAMES})


def write_pulse(path: str, pulse: Pulse, params: Parameters, overwrite: bool = True) -> None:
    """Add (or replace) `pulse` as ``pulses/<label>`` in `path`, atomically."""

    def fill(h5):
        if "parameters" in h5:
            old = read_parameters(h5)
            if old != params:
                raise SchemaError(f"{path}: stored parameters differ from this run's")
        else:
            write_parameters(h5, params)
        pulses = h5.require_group("pulses")
        if pulse.label in pulses:
            if not overwrite:
                raise SchemaError(f"{path}: pulse {pulse.label} already present")
            del pulses[pulse.label]
        grp = pulses.create_group(pulse.label)
        for name, unit in DATASETS.items():
            ds = grp.create_dataset(name, data=np.asarray(getattr(pulse, name), dtype=float))
            ds.attrs["units"] = unit
        for name in ATTRS:
            val = getattr(pulse, name)
            grp.attrs[name] = np.bool_(val) if name == "converged" else val
        for key, val in pulse.extra.items():
            grp.attrs[key] = val

    atomic_update(path, fill)


def _group_to_pulse(grp) -> Pulse:
    missing = [n for n in DATASETS if n not in grp] + [n for n in ATTRS if n not in grp.attrs]
    if missing:
        raise SchemaError(f"group {grp.name} is not a slippulse pulse: missing {missing}")
    xi = np.asarray(grp["xi"][...], dtype=float)
    n = xi.size
    arrays = {name: np.asarray(grp[name][...], dtype=float) for name in DATASETS}
    if any(a.shape != (n,) for a in arrays.values()):
        raise SchemaError(f"group {grp.name}: datasets must be 1-D of equal length")
    if n < 2 or np.any(np.diff(xi) <= 0):
        raise SchemaError(f"group {grp.name}: xi must be strictly ascending")
    kw = {name: grp.attrs[name] for name in ATTRS}
    kw["converged"] = bool(kw["converged"])
    kw["n_points"] = int(kw["n_points"])
    kw["mode"] = str(kw["mode"])
    for name in ATTRS:
        if name not in ("converged", "n_points", "mode"):
            kw[name] = float(kw[name])
    extra = {k: grp.attrs[k] for k in grp.attrs if k not in ATTRS}
    return Pulse(**arrays, **kw, extra=extra)


def list_pulses(path: str) -> list[str]:
    """Labels of the pulses in a file, sorted by decreasing τ_d."""
    with h5py.File(path, "r") as h5:
        if "pulses" not in h5:
            raise SchemaError(f"{path}: no 'pulses' group")
        labels = list(h5["pulses"].keys())
    return sorted(labels, key=lambda s: -float(s[2:]))


def read_pulse(path: str, label: str | None = None) -> tuple[Pulse, Parameters]:
    """Read one pulse (the only one, or `label`) and the parameters it was computed with."""
    try:
        h5 = h5py.File(path, "r")
    except OSError as exc:
        raise SchemaError(f"{path}: not a readable HDF5 file ({exc})") from None
    with h5:
        params = read_parameters(h5)
        if "pulses" not in h5:
            raise SchemaError(f"{path}: no 'pulses' group")
        labels = list(h5["pulses"].keys())
        if label is None:
            if len(labels) != 1:
                raise SchemaError(f"{path}: holds {len(labels)} pulses, name one of {labels}")
            label = labels[0]
        if label not in h5["pulses"]:
            raise SchemaError(f"{path}: no pulse {label!r}; present: {labels}")
        return _group_to_pulse(h5["pulses"][label]), params
