"""The rate-and-state friction law (paper Eqs. S2–S3): one law, used by the steady solver and the SBI.

    f(v, φ) = [1 + b ln(1 + φ/φ*)] · [ f0 |v|/√(v² + v*²) + α ln(1 + |v|/v*) ]
    g(v, φ) = 1 − φ √(v² + v*²) / D          (dφ/dt = g; −β c_s dφ/dξ = g in the steady frame)

(f0/√(1+(v*/v)²) = f0|v|/√(v²+v*²) is written in the form that stays finite at v = 0.)
τ = σ f is the strength *magnitude*; v is the slip-rate magnitude, v ≥ 0 in this project.

Every kernel is a numba ufunc (``numba.vectorize``): it broadcasts over numpy arrays from Python and
can be called on scalars from inside ``numba.njit`` code, so the SBI time stepper and the steady
solver evaluate the very same compiled law. The trailing scalar arguments are always
``(f0, b, alpha, v_star, phi_star, D)`` or the subset named in each signature; ``Parameters.law_args``
gives them in that order.
"""
from __future__ import annotations

import math

import numpy as np
from numba import vectorize

_SIG7 = ["float64(float64, float64, float64, float64, float64, float64, float64)"]
_SIG8 = ["float64(float64, float64, float64, float64, float64, float64, float64, float64)"]
_SIG4 = ["float64(float64, float64, float64, float64)"]
_SIG3 = ["float64(float64, float64, float64)"]


@vectorize(_SIG8, cache=True)
def f(v, phi, f0, b, alpha, v_star, phi_star, D):
    """Friction coefficient f(v, φ) (dimensionless). D is unused; kept for a uniform signature."""
    av = abs(v)
    return (1.0 + b * math.log1p(phi / phi_star)) * (
        f0 * av / math.sqrt(v * v + v_star * v_star) + alpha * math.log1p(av / v_star))


@vectorize(_SIG8, cache=True)
def df_dv(v, phi, f0, b, alpha, v_star, phi_star, D):
    """∂f/∂v for v > 0: A(φ) [f0 v*²/(v²+v*²)^{3/2} + α/(v* + v)]."""
    r2 = v * v + v_star * v_star
    return (1.0 + b * math.log1p(phi / phi_star)) * (
        f0 * v_star * v_star / (r2 * math.sqrt(r2)) + alpha / (v_star + abs(v)))


@vectorize(_SIG8, cache=True)
def df_dphi(v, phi, f0, b, alpha, v_star, phi_star, D):
    """∂f/∂φ = b/(φ* + φ) · [f0|v|/√(v²+v*²) + α ln(1+|v|/v*)]."""
    av = abs(v)
    return b / (phi_star + phi) * (
        f0 * av / math.sqrt(v * v + v_star * v_star) + alpha * math.log1p(av / v_star))


@vectorize(_SIG4, cache=True)
def g(v, phi, v_star, D):
    """State rate g(v, φ) = 1 − φ √(v² + v*²)/D (dimensionless: dφ/dt in s/s)."""
    return 1.0 - phi * math.sqrt(v * v + v_star * v_star) / D


@vectorize(_SIG4, cache=True)
def dg_dv(v, phi, v_star, D):
    """∂g/∂v = −φ v / (D √(v² + v*²))."""
    return -phi * v / (D * math.sqrt(v * v + v_star * v_star))


@vectorize(_SIG3, cache=True)
def heal_rate(v, v_star, D):
    """w(v) = √(v² + v*²)/D, 1/s, so that g = 1 − w φ and ∂g/∂φ = −w."""
    return math.sqrt(v * v + v_star * v_star) / D


@vectorize(_SIG3, cache=True)
def phi_ss(v, v_star, D):
    """Steady state φ_ss(v) = D/√(v² + v*²) (root of g), s."""
    return D / math.sqrt(v * v + v_star * v_star)


@vectorize(_SIG7, cache=True)
def f_ss(v, f0, b, alpha, v_star, phi_star, D):
    """Steady-state friction coefficient f(v, φ_ss(v))."""
    phi = D / math.sqrt(v * v + v_star * v_star)
    av = abs(v)
    return (1.0 + b * math.log1p(phi / phi_star)) * (
        f0 * av / math.sqrt(v * v + v_star * v_star) + alpha * math.log1p(av / v_star))


@vectorize(_SIG7, cache=True)
def df_ss_dlnv(v, f0, b, alpha, v_star, phi_star, D):
    """d f_ss / d ln v = v [∂f/∂v + ∂f/∂φ · dφ_ss/dv], dφ_ss/dv = −D v/(v²+v*²)^{3/2}, for v > 0."""
    r2 = v * v + v_star * v_star
    r = math.sqrt(r2)
    phi = D / r
    A = 1.0 + b * math.log1p(phi / phi_star)
    B = f0 * v / r + alpha * math.log1p(v / v_star)
    dB = f0 * v_star * v_star / (r2 * r) + alpha / (v_star + v)
    dphi = -D * v / (r2 * r)
    return v * (A * dB + b / (phi_star + phi) * B * dphi)


@vectorize(_SIG3, cache=True)
def state_step(phi, w, dt):
    """Exact state update over dt at frozen healing rate w = √(v²+v*²)/D for dφ/dt = 1 − w φ.

    φ(t+dt) = φ_ss + (φ − φ_ss) e^{−w dt}, written as φ e^{−x} − dt·expm1(−x)/x with x = w dt:
    exact at constant v, unconditionally stable and stiff-accurate (→ 1/w as w dt → ∞).
    Within a factor 2 of φ_ss the equivalent form φ_ss + (φ − φ_ss) e^{−x} is used: it keeps the
    creeping rest state exactly fixed (the first form drifted by ~1e-16 φ per step, measured).
    """
    x = w * dt
    if x < 1e-300:
        return phi + dt
    phi_ss = 1.0 / w
    d = phi - phi_ss
    if abs(d) <= phi_ss:
        # near steady state: φ_ss is an exact fixed point of this form (no rounding drift)
        return phi_ss + d * math.exp(-x)
    return phi * math.exp(-x) - dt * math.expm1(-x) / x


class RateStateFriction:
    """The friction law bound to a parameter set: the object both solvers use.

    Parameters
    ----------
    params : slippulse.core.params.Parameters
        Table-I parameters (SI units).
    """

    def __init__(self, params):
        self.params = params
        self.args = params.law_args
        self.sigma = params.sigma

    def f(self, v, phi):
        return f(v, phi, *self.args)

    def tau(self, v, phi):
        """Frictional strength σ f(v, φ), Pa."""
        return self.sigma * f(v, phi, *self.args)

    def df_dv(self, v, phi):
        return df_dv(v, phi, *self.args)

    def df_dphi(self, v, phi):
        return df_dphi(v, phi, *self.args)

    def g(self, v, phi):
        return g(v, phi, self.params.v_star, self.params.D)

    def dg_dv(self, v, phi):
        return dg_dv(v, phi, self.params.v_star, self.params.D)

    def heal_rate(self, v):
        return heal_rate(v, self.params.v_star, self.params.D)

    def phi_ss(self, v):
        return phi_ss(v, self.params.v_star, self.params.D)

    def tau_ss(self, v):
        return self.sigma * f_ss(np.asarray(v, dtype=float), *self.args)
