"""Physical parameters (Table I of Pomyalov et al., PRE 2023) and the scales derived from them.

All quantities are SI. The derived scales (τ_min, v_min, the local maximum of τ_ss, v_stick, v_ss)
are roots of smooth one-dimensional equations in ln v, solved with scipy's Brent method to a
relative tolerance of a few ulps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np
from scipy.optimize import brentq

from . import friction as _fr

#: Critical crack-like fracture energy G_c* used to scale L (paper, Fig. 3 caption), J/m², for the
#: Table-I parameters. It is not an input: it only sets the natural length μ G_c*/τ_min² of L̃.
G_C_STAR = 0.65
#: G_c*/(σ D) = 0.65 J/m² / (1 MPa · 0.5 µm) = 1.3: the paper's G_c* as a dimensionless number.
#: For other parameters G_c* = 1.3 σ D (:attr:`Parameters.G_c_star`), so that L̃ = L τ_min²/(μ G_c*)
#: is invariant under the exact similarities of the equations (a fracture energy is a stress times a
#: slip, σ D); for Table I it is the paper's 0.65 J/m². It is a scale, not a measured G_c: for a law
#: of other f0, b, α the measured G_c (``steady analyse``) differs from it.
GC_OVER_SIGMA_D = 1.3


class ParameterError(ValueError):
    """Bad user input: the message names the parameter and its valid range."""


@dataclass(frozen=True)
class Parameters:
    """Material and interface parameters of the paper's Table I.

    Attributes
    ----------
    mu : float
        Shear modulus μ, Pa.
    sigma : float
        Normal stress σ, Pa.
    c_s : float
        Shear wave speed c_s, m/s.
    D : float
        Memory length D, m.
    b : float
        State (aging) coefficient b, dimensionless.
    v_star : float
        Regularisation velocity v*, m/s.
    f0 : float
        Rate coefficient f0, dimensionless.
    phi_star : float
        Aging onset time φ*, s.
    alpha : float
        Viscous-like rate-strengthening coefficient α, dimensionless.
    """

    mu: float = 9e9
    sigma: float = 1e6
    c_s: float = 2739.0
    D: float = 5e-7
    b: float = 0.075
    v_star: float = 1e-7
    f0: float = 0.28
    phi_star: float = 3.3e-4
    alpha: float = 0.005

    UNITS = {"mu": "Pa", "sigma": "Pa", "c_s": "m/s", "D": "m", "b": "1", "v_star": "m/s",
             "f0": "1", "phi_star": "s", "alpha": "1"}

    def __post_init__(self):
        for fld in fields(self):
            val = getattr(self, fld.name)
            if not (isinstance(val, (int, float, np.floating)) and math.isfinite(val) and val > 0):
                raise ParameterError(
                    f"parameter {fld.name}={val!r} is invalid: must be a finite number > 0 "
                    f"({self.UNITS[fld.name]})")
        if self.f0 * self.b <= self.alpha:
            raise ParameterError(
                f"parameters f0*b={self.f0 * self.b:g} must exceed alpha={self.alpha:g}: "
                "otherwise tau_ss(v) has no velocity-weakening branch and no N shape")

    # ------------------------------------------------------------------ friction shortcuts
    @property
    def law_args(self) -> tuple:
        """(f0, b, alpha, v_star, phi_star, D): the scalars the numba friction kernels take."""
        return (self.f0, self.b, self.alpha, self.v_star, self.phi_star, self.D)

    def as_dict(self) -> dict:
        return {fld.name: float(getattr(self, fld.name)) for fld in fields(self)}

    def tau_ss(self, v):
        """Steady-state friction stress τ_ss(v) = σ f(v, φ_ss(v)), Pa."""
        return self.sigma * _fr.f_ss(np.asarray(v, dtype=float), *self.law_args)

    def _dtau_ss_dlnv(self, lnv: float) -> float:
        return self.sigma * float(_fr.df_ss_dlnv(math.exp(lnv), *self.law_args))

    # ------------------------------------------------------------------ derived scales
    @cached_property
    def _extrema(self) -> tuple[float, float]:
        """ln v of the local maximum and of the minimum of τ_ss (roots of dτ_ss/d ln v)."""
        grid = np.linspace(math.log(self.v_star) - 30.0, math.log(self.c_s), 4001)
        d = np.array([self._dtau_ss_dlnv(x) for x in grid])
        sign_change = np.nonzero(np.sign(d[:-1]) != np.sign(d[1:]))[0]
        roots = [brentq(self._dtau_ss_dlnv, grid[k], grid[k + 1], xtol=1e-15, rtol=8.9e-16)
                 for k in sign_change]
        if len(roots) != 2 or d[0] <= 0:
            raise ParameterError(n_shape_message(self, roots, d[0] > 0))
        return roots[0], roots[1]

    @cached_property
    def v_peak(self) -> float:
        """Slip rate of the local maximum of τ_ss, m/s."""
        return math.exp(self._extrema[0])

    @cached_property
    def tau_peak(self) -> float:
        """Local maximum of τ_ss (static-friction-like peak), Pa."""
        return float(self.tau_ss(self.v_peak))

    @cached_property
    def v_min(self) -> float:
        """Slip rate of the minimum of τ_ss, m/s."""
        return math.exp(self._extrema[1])

    @cached_property
    def tau_min(self) -> float:
        """Minimum of τ_ss on the velocity-weakening/strengthening crossover, Pa."""
        return float(self.tau_ss(self.v_min))

    @cached_property
    def L0(self) -> float:
        """Elasto-frictional length L0 = π μ D / (σ (f0 b − α)), m."""
        return math.pi * self.mu * self.D / (self.sigma * (self.f0 * self.b - self.alpha))

    @property
    def G_c_star(self) -> float:
        """Fracture-energy scale G_c* = 1.3 σ D, J/m² (0.65 J/m² for Table I; :data:`GC_OVER_SIGMA_D`)."""
        return GC_OVER_SIGMA_D * self.sigma * self.D

    @cached_property
    def L_Gc(self) -> float:
        """Natural length of L: μ G_c* / τ_min², m (G_c* = 1.3 σ D = 0.65 J/m² for Table I)."""
        return self.mu * self.G_c_star / self.tau_min ** 2

    def check_tau_d(self, tau_d: float) -> None:
        """Raise ParameterError unless τ_min < τ_d < τ_peak (Pa)."""
        if not (isinstance(tau_d, (int, float, np.floating)) and math.isfinite(tau_d)):
            raise ParameterError(f"tau_d={tau_d!r} must be a finite number")
        if tau_d <= self.tau_min:
            raise ParameterError(
                f"tau_d/tau_min={tau_d / self.tau_min:.6g} is invalid: must be > 1 "
                "(tau_d <= tau_min: no sliding branch, no pulse can exist) and < "
                f"{self.tau_peak / self.tau_min:.6g} (local maximum of tau_ss)")
        if tau_d >= self.tau_peak:
            raise ParameterError(
                f"tau_d/tau_min={tau_d / self.tau_min:.6g} is invalid: must be < "
                f"{self.tau_peak / self.tau_min:.6g} (at or above the local maximum of tau_ss "
                "there is no stick state) and > 1")

    def _root_tau_ss(self, tau_d: float, lo: float, hi: float) -> float:
        fun = lambda x: float(self.tau_ss(math.exp(x))) - tau_d
        return math.exp(brentq(fun, lo, hi, xtol=1e-15, rtol=8.9e-16))

    def v_stick(self, tau_d: float) -> float:
        """Smallest root of τ_ss(v) = τ_d (the creeping rest state), m/s."""
        self.check_tau_d(tau_d)
        lo = math.log(self.v_star) - 60.0
        return self._root_tau_ss(tau_d, lo, self._extrema[0])

    def v_ss(self, tau_d: float) -> float:
        """Largest root of τ_ss(v) = τ_d (velocity-strengthening sliding branch), m/s."""
        self.check_tau_d(tau_d)
        hi = self._extrema[1] + 1.0
        while float(self.tau_ss(math.exp(hi))) < tau_d:
            hi += 5.0
            if hi > math.log(1e6 * self.c_s):
                raise ParameterError(f"tau_d={tau_d:g} Pa has no root on the strengthening branch")
        return self._root_tau_ss(tau_d, self._extrema[1], hi)

    def phi_rest(self, tau_d: float) -> float:
        """State ahead of the pulse, φ_ss(v_stick) = D/√(v_stick² + v*²), s."""
        v = self.v_stick(tau_d)
        return float(_fr.phi_ss(v, self.v_star, self.D))

    def F3(self, beta):
        """Mode-III inertia factor F_III(β) = √(1−β²)/(2π β c_s), s/m."""
        beta = np.asarray(beta, dtype=float)
        return np.sqrt(1.0 - beta ** 2) / (2.0 * math.pi * beta * self.c_s)

    def dF3_dbeta(self, beta):
        """dF_III/dβ = −1/(2π c_s β² √(1−β²)), s/m."""
        beta = np.asarray(beta, dtype=float)
        return -1.0 / (2.0 * math.pi * self.c_s * beta ** 2 * np.sqrt(1.0 - beta ** 2))


DEFAULT = Parameters()


# ---------------------------------------------------------------------- parameters as user input
#: Valid range of each parameter, (low, high) open at both ends, with its unit. Dimensional values
#: have no upper bound; the dimensionless friction constants are bounded by 10 (f0, b, α of
#: rate-and-state laws are O(0.001-1)). Beyond the ranges, τ_ss must be N-shaped (:func:`validate`).
RANGES = {"mu": (0.0, math.inf), "sigma": (0.0, math.inf), "c_s": (0.0, math.inf),
          "D": (0.0, math.inf), "b": (0.0, 10.0), "v_star": (0.0, math.inf),
          "f0": (0.0, 10.0), "phi_star": (0.0, math.inf), "alpha": (0.0, 10.0)}
NAMES = tuple(RANGES)


def _range_text(name: str) -> str:
    lo, hi = RANGES[name]
    unit = Parameters.UNITS[name]
    return (f"in ({lo:g}, {hi:g})" if math.isfinite(hi) else f"> {lo:g}") + \
        ("" if unit == "1" else f" {unit}")


def n_shape_message(params: "Parameters", roots, rising_at_creep: bool) -> str:
    """One-line reason why τ_ss(v) of ``params`` is not N-shaped (``roots``: ln v of the extrema
    of τ_ss found for v below c_s)."""
    head = "parameters do not give an N-shaped tau_ss(v) (a local maximum, then a minimum below c_s)"
    if not rising_at_creep:
        return f"{head}: tau_ss does not rise at creep rates (v << v_star)"
    if not roots:
        return (f"{head}: tau_ss(v) is monotonic for v < c_s, with no local maximum and no minimum;"
                " a law without a minimum has no steady pulse")
    if len(roots) == 1:
        return (f"{head}: tau_ss has a local maximum at v = {math.exp(roots[0]):.3g} m/s but no "
                f"minimum below c_s = {params.c_s:g} m/s; a law without a minimum has no steady "
                "pulse (raise alpha or lower f0*b)")
    return f"{head}: tau_ss has {len(roots)} extrema, not 2"


def validate(params: "Parameters") -> "Parameters":
    """Check the N shape of τ_ss (a local maximum followed by a minimum below c_s); return params.

    Raises
    ------
    ParameterError
        Naming what is missing (e.g. "a law without a minimum has no steady pulse").
    """
    params._extrema            # noqa: B018 (computed, cached, raises ParameterError)
    return params


def check_value(name: str, value, origin: str = "") -> float:
    """``value`` as a float if ``name`` is a known parameter and the value is a number in its
    range; else ParameterError naming the parameter, the origin and the valid range."""
    where = f"{origin}: " if origin else ""
    if name not in RANGES:
        raise ParameterError(f"{where}unknown parameter {name!r}; known: {', '.join(NAMES)}")
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{where}parameter {name}={value!r} is invalid: must be a number "
                             f"{_range_text(name)}")
    val = float(value)
    lo, hi = RANGES[name]
    if not (math.isfinite(val) and lo < val < hi):
        raise ParameterError(f"{where}parameter {name}={val!r} is invalid: must be a finite number "
                             f"{_range_text(name)}")
    return val


def read_params_file(path: str) -> dict:
    """The ``[params]`` table of a TOML file (the schema of dynamic configs), checked by name and
    range. Other tables (a whole dynamic config) are ignored; a file without ``[params]`` is an
    error."""
    import tomllib

    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except OSError as exc:
        raise ParameterError(f"params={path!r}: cannot read it ({exc.strerror})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ParameterError(f"params={path!r} is not valid TOML: {exc}") from None
    table = data.get("params")
    if not isinstance(table, dict):
        raise ParameterError(f"params={path!r} has no [params] table (keys: {', '.join(NAMES)})")
    return {k: check_value(k, v, path) for k, v in table.items()}


def parse_param_set(item: str) -> tuple[str, float]:
    """``params.NAME=VALUE`` → (NAME, value), checked by name and range."""
    if "=" not in item:
        raise ParameterError(f"--set {item!r}: expected params.NAME=VALUE")
    key, raw = (s.strip() for s in item.split("=", 1))
    if not key.startswith("params."):
        raise ParameterError(f"--set {item!r}: expected params.NAME=VALUE (NAME one of "
                             f"{', '.join(NAMES)})")
    name = key[len("params."):]
    try:
        value = float(raw)
    except ValueError:
        value = raw
    return name, check_value(name, value, "--set")


def explicit_params(path: str | None = None, sets=()) -> dict:
    """The parameters a user gave: the ``[params]`` of ``path`` (if any), then each
    ``params.NAME=VALUE`` of ``sets``; {name: value}, each checked by name and range."""
    given = read_params_file(path) if path else {}
    for item in sets:
        name, val = parse_param_set(item)
        given[name] = val
    return given


def resolve_params(path: str | None = None, sets=(), base: "Parameters | None" = None) -> Parameters:
    """Parameters from ``base`` (default Table I), then the file's ``[params]``, then ``sets``;
    validated (ranges, f0 b > α, the N shape of τ_ss)."""
    base = DEFAULT if base is None else base
    merged = {**base.as_dict(), **explicit_params(path, sets)}
    return validate(Parameters(**merged))


def differing(a: "Parameters | dict", b: "Parameters | dict", rtol: float = 1e-12) -> list[str]:
    """Names of the parameters whose values differ between ``a`` and ``b`` (relative ``rtol``);
    dicts may hold a subset of the names (only those are compared)."""
    da = a.as_dict() if isinstance(a, Parameters) else dict(a)
    db = b.as_dict() if isinstance(b, Parameters) else dict(b)
    return [n for n in NAMES if n in da and n in db
            and not abs(da[n] - db[n]) <= rtol * max(abs(da[n]), abs(db[n]))]


def describe_difference(a, b, what_a: str, what_b: str) -> str:
    """'b: 0.075 (what_a) vs 0.08 (what_b); ...' for the differing parameters (empty if none)."""
    da = a.as_dict() if isinstance(a, Parameters) else dict(a)
    db = b.as_dict() if isinstance(b, Parameters) else dict(b)
    return "; ".join(f"{n}={da[n]:.10g} ({what_a}) vs {db[n]:.10g} ({what_b})"
                     for n in differing(da, db))
