"""Configuration of dynamic (SBI) runs: defaults → TOML file → ``--set section.key=value``.

Every key has a default below; a key that is not listed (a typo) is an error, and so is a value of
the wrong type. The resolved configuration is a plain nested dict, stored in the output file.

Sections and keys (units SI):

``[grid]``      n (points, even), length (periodic domain λ, m)
``[params]``    the Table-I parameters (see slippulse.core.params.Parameters)
``[load]``      tau_d_ratio (τ_d/τ_min; τ_load = τ_d + η v_stick so that creep has τ = τ_d)
``[initial]``   kind ("creep" | "gaussian"), amplitude (m/s), width (m), position (m)
``[time]``      stepping ("fixed" | "adaptive"), beta_cfl, xi, xi_stab, growth, ladder,
                dt_max (s; 0 = no cap), t_end (s), max_steps (0 = no limit)
``[history]``   policy ("full" | "window" | "soe" | "quasi_dynamic"), window_periods, window_max_steps,
                soe_x_min, soe_x_max, soe_h
``[stepper]``   name ("pc2")
``[fft]``       threads, planner ("estimate" | "measure" | "patient")
``[output]``    file, snapshot_every (steps), checkpoint_every (steps)
"""
from __future__ import annotations

import copy
import math
import tomllib
from dataclasses import fields

from ..core.errors import UsageError
from ..core.params import Parameters

DEFAULTS: dict = {
    "grid": {"n": 1024, "length": 1.0},
    "params": {f.name: float(f.default) for f in fields(Parameters)},
    "load": {"tau_d_ratio": 1.2},
    "initial": {"kind": "creep", "amplitude": 0.0, "width": 0.01, "position": 0.5},
    "time": {"stepping": "fixed", "beta_cfl": 0.5, "xi": 0.1, "xi_stab": 0.5, "growth": 1.2, "ladder": 1.189207115002721,
             "dt_max": 0.0, "t_end": 1e-3, "max_steps": 0},
    "history": {"policy": "soe", "window_periods": 4.0, "window_max_steps": 2000,
                "soe_x_min": 1e-8, "soe_x_max": 1e8, "soe_h": 0.5},
    "stepper": {"name": "pc2"},
    "fft": {"threads": 1, "planner": "estimate"},
    "output": {"file": "dynamic_run.h5", "snapshot_every": 100, "checkpoint_every": 1000},
}

#: Keys a resumed run may change (to extend it or move its output).
RESUME_MUTABLE = {"time.t_end", "time.max_steps", "output.file"}


def _coerce(key: str, value, default):
    """Check ``value`` against the type of ``default`` (ints are accepted for floats)."""
    if isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if ok:
            value = float(value)
            if not math.isfinite(value):
                raise UsageError(f"config key {key}={value!r} must be finite")
    else:
        ok = isinstance(value, str)
    if not ok:
        raise UsageError(f"config key {key}={value!r} has the wrong type: expected "
                         f"{type(default).__name__} (default {default!r})")
    return value


def merge(base: dict, update: dict, origin: str) -> dict:
    """Return ``base`` updated by ``update``; unknown sections or keys raise UsageError."""
    out = copy.deepcopy(base)
    for section, table in update.items():
        if section not in out:
            raise UsageError(f"{origin}: unknown config section [{section}]; known: "
                             f"{', '.join(sorted(out))}")
        if not isinstance(table, dict):
            raise UsageError(f"{origin}: [{section}] must be a table")
        for key, value in table.items():
            if key not in out[section]:
                raise UsageError(f"{origin}: unknown config key {section}.{key}; known in "
                                 f"[{section}]: {', '.join(sorted(out[section]))}")
            out[section][key] = _coerce(f"{section}.{key}", value, out[section][key])
    return out


def parse_set(item: str) -> dict:
    """``section.key=value`` → {section: {key: value}}; the value is read as TOML, else as a string."""
    if "=" not in item or "." not in item.split("=", 1)[0]:
        raise UsageError(f"--set {item!r}: expected section.key=value")
    path, raw = item.split("=", 1)
    section, key = path.strip().split(".", 1)
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return {section: {key: value}}


def load_config(path: str | None = None, sets: list[str] | tuple = ()) -> dict:
    """Defaults, then the TOML file at ``path`` (if any), then each ``--set`` override."""
    cfg = copy.deepcopy(DEFAULTS)
    if path is not None:
        try:
            with open(path, "rb") as fh:
                data = tomllib.load(fh)
        except OSError as exc:
            raise UsageError(f"cannot read config {path}: {exc.strerror}")
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise UsageError(f"config {path} is not valid TOML: {exc}")
        cfg = merge(cfg, data, path)
    for item in sets:
        cfg = merge(cfg, parse_set(item), "--set")
    return cfg


def flatten(cfg: dict) -> dict:
    """{"section.key": value} view of a config."""
    return {f"{s}.{k}": v for s, table in cfg.items() for k, v in table.items()}


def diff_keys(a: dict, b: dict) -> list[str]:
    """Keys whose values differ between two configs."""
    fa, fb = flatten(a), flatten(b)
    return sorted(k for k in set(fa) | set(fb) if fa.get(k) != fb.get(k))


def build_stepper(cfg: dict):
    """Problem and solver from a resolved config: the stepper with its initial state set."""
    from ..core.params import ParameterError
    from .stepper import RateStateInterface, TimeStepRule, make_stepper

    params = Parameters(**cfg["params"])
    check_ranges(cfg, params)
    tau_d = cfg["load"]["tau_d_ratio"] * params.tau_min
    law = RateStateInterface(params, tau_d)
    tm = cfg["time"]
    rule = TimeStepRule(kind=tm["stepping"], beta_cfl=tm["beta_cfl"], xi=tm["xi"],
                        xi_stab=tm["xi_stab"], growth=tm["growth"], ladder=tm["ladder"],
                        dt_max=tm["dt_max"] if tm["dt_max"] > 0 else math.inf)
    h = cfg["history"]
    options = {"full": {},
               "window": {"periods": h["window_periods"], "max_steps": h["window_max_steps"]},
               "soe": {"x_min": h["soe_x_min"], "x_max": h["soe_x_max"], "h": h["soe_h"]},
               "quasi_dynamic": {}}
    if h["policy"] not in options:
        raise ParameterError(f"history.policy={h['policy']!r} must be one of {sorted(options)}")
    _check_fft(cfg["fft"])
    st = make_stepper(cfg["stepper"]["name"], params, cfg["grid"]["n"], cfg["grid"]["length"], law,
                      rule=rule, history=h["policy"], history_options=options[h["policy"]],
                      threads=cfg["fft"]["threads"], planner=cfg["fft"]["planner"])
    ini = cfg["initial"]
    if ini["kind"] == "creep":
        st.set_creep()
    elif ini["kind"] == "gaussian":
        st.set_gaussian(ini["amplitude"], ini["width"], ini["position"])
    else:
        raise ParameterError(f"initial.kind={ini['kind']!r} must be 'creep' or 'gaussian'")
    for key in ("snapshot_every", "checkpoint_every"):
        if cfg["output"][key] < 1:
            raise ParameterError(f"output.{key}={cfg['output'][key]!r} must be >= 1 (steps)")
    if cfg["time"]["max_steps"] < 0 or not (0 < cfg["time"]["t_end"] < math.inf):
        raise ParameterError(f"time.t_end={cfg['time']['t_end']!r} must be finite and > 0 (s) and "
                             f"time.max_steps={cfg['time']['max_steps']!r} >= 0 (0 = no limit)")
    return st


#: Grid spacing λ/n a run may use, in elasto-frictional lengths L0 = π μ D/(σ(f0 b − α)): finer
#: than 1e-6 L0 the time step (CFL) underflows any useful t_end; coarser than 10 L0 the grid
#: resolves no pulse or nucleus (the smallest dynamic length is a fraction of L0).
DX_RANGE_L0 = (1e-6, 10.0)
#: Most nodes of the sum-of-exponentials history (ln(x_max/x_min)/h): each holds one complex
#: array of n values.
MAX_SOE_NODES = 2000


def check_ranges(cfg: dict, params: Parameters) -> None:
    """Ranges the stepper can handle, checked before anything is allocated (ParameterError
    naming the key and the valid range): grid spacing (:data:`DX_RANGE_L0`), the history
    settings, the load."""
    from ..core.params import ParameterError

    from .stepper import MAX_GRID_POINTS
    n, length = cfg["grid"]["n"], cfg["grid"]["length"]
    if not (isinstance(n, int) and 4 <= n <= MAX_GRID_POINTS and n % 2 == 0):
        raise ParameterError(f"grid.n={n!r} is invalid: must be an even integer in [4, "
                             f"{MAX_GRID_POINTS}]")
    lo, hi = (f * params.L0 for f in DX_RANGE_L0)
    if not (isinstance(n, int) and n > 0 and 0 < length < math.inf and lo <= length / n <= hi):
        raise ParameterError(f"grid.length={length!r} is invalid: with grid.n={n!r} the spacing "
                             f"must lie in [{lo:.3g}, {hi:.3g}] m ({DX_RANGE_L0[0]:g} to "
                             f"{DX_RANGE_L0[1]:g} L0), i.e. length in [{lo * n:.3g}, "
                             f"{hi * n:.3g}] m")
    h = cfg["history"]
    x_min, x_max, step = h["soe_x_min"], h["soe_x_max"], h["soe_h"]
    if not 0 < x_min < x_max < math.inf:
        raise ParameterError(f"history.soe_x_min={x_min!r} and soe_x_max={x_max!r} are invalid: "
                             "need 0 < soe_x_min < soe_x_max (finite)")
    if not 0 < step <= 2:
        raise ParameterError(f"history.soe_h={step!r} is invalid: must be in (0, 2]")
    nodes = math.log(x_max / x_min) / step
    if nodes > MAX_SOE_NODES:
        raise ParameterError(f"history.soe_h={step!r} with soe_x_min={x_min:g}, soe_x_max="
                             f"{x_max:g} gives {nodes:.3g} nodes; at most {MAX_SOE_NODES}")
    if not 0 < h["window_periods"] <= 1e3:
        raise ParameterError(f"history.window_periods={h['window_periods']!r} is invalid: must "
                             "be in (0, 1000]")
    if not 1 <= h["window_max_steps"] <= 10**7:
        raise ParameterError(f"history.window_max_steps={h['window_max_steps']!r} is invalid: "
                             "must be in [1, 1e7]")
    ratio = cfg["load"]["tau_d_ratio"]
    hi_ratio = params.tau_peak / params.tau_min
    if not 0 < ratio < hi_ratio:
        raise ParameterError(f"load.tau_d_ratio={ratio!r} is invalid: must be in (0, "
                             f"{hi_ratio:.4f}) (below the peak of tau_ss)")


#: Most FFTW threads a run may ask for.
MAX_THREADS = 256


def _check_fft(fft: dict) -> None:
    """``[fft]``: threads an integer in [1, MAX_THREADS], planner one of the FFTW efforts
    (ParameterError naming the key, before any plan is made)."""
    from ..core.params import ParameterError
    from .fft import PLANNERS

    n = fft["threads"]
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_THREADS:
        raise ParameterError(f"fft.threads={n!r} is invalid: must be an integer in "
                             f"[1, {MAX_THREADS}]")
    if fft["planner"] not in PLANNERS:
        raise ParameterError(f"fft.planner={fft['planner']!r} is invalid: must be one of "
                             f"{', '.join(sorted(PLANNERS))}")
