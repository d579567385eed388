"""The growth rates of record (the ``[spectrum."LABEL"]`` entries of a records TOML, e.g.
docs/results/records.toml: s L/c_p ± err and L) and their ratio to the slope of the family,
R = s L/c_p / |dτ_d/d ln L| (docs/results.md §2: a real eigenvalue crosses zero only at a fold
of the family in τ_d, and near one s L/c_p ≈ R |dτ_d/d ln L|).
"""
from __future__ import annotations

import tomllib

import numpy as np

from ..core.h5io import label_decimals, label_ratio
from .law import family_curve, family_slope, fold_ratio


def read_rates(path):
    """The rates of record of ``path``, sorted by L: dict of arrays ``label``, ``tau_d_ratio``
    (from the label), ``L`` (m), ``s`` and ``s_err`` (s L/c_p).

    Raises ValueError naming what is missing (no file is a FileNotFoundError)."""
    with open(path, "rb") as fh:
        try:
            rec = tomllib.load(fh).get("spectrum", {})
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"not a TOML file ({exc})") from None
    try:
        labels = sorted(rec, key=lambda k: rec[k]["L"])
        out = {"label": labels,
               "tau_d_ratio": np.array([label_ratio(k) for k in labels], float),
               "L": np.array([rec[k]["L"] for k in labels], float),
               "s": np.array([rec[k]["s_per_L"]["value"] for k in labels], float),
               "s_err": np.array([rec[k]["s_per_L"]["err"] for k in labels], float)}
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"a [spectrum.\"LABEL\"] entry lacks L or s_per_L ({exc})") from None
    if not labels:
        raise ValueError("no [spectrum.\"LABEL\"] entries")
    return out


def records_fold_ratio(rates, families):
    """R ± err at each rate of record, the slope dτ_d/d ln L at its L taken from the converged
    pulses of the family files ``families`` (any march of the one family), or, beyond their
    deepest pulse, from the records' own (τ_d, L) points (coarser: the rounding of each label's
    τ_d over the spacing in ln L to the nearest record is added to its error).

    Returns a dict: the keys of ``rates`` and ``slope``, ``slope_err``, ``R``, ``R_err``,
    ``source`` ('family' or 'records'), and ``curve`` (:func:`.law.family_curve`)."""
    L, tau = rates["L"], rates["tau_d_ratio"]
    curve = family_curve(families)
    g, ge = family_slope(curve["tau_d_ratio"], curve["L"], curve["beta"], at_L=L)
    src = np.where(np.isfinite(g), "family", "records")
    g2, ge2 = family_slope(tau, L)                       # along ln L: no β in the records
    half = np.array([0.5 * 10.0 ** -label_decimals(k) for k in rates["label"]])
    dx = np.diff(np.log(L))
    near = np.minimum(np.r_[np.inf, dx], np.r_[dx, np.inf])
    ge2 = np.hypot(ge2, np.sqrt(2.0) * half / near)
    g, ge = np.where(np.isfinite(g), g, g2), np.where(np.isfinite(ge), ge, ge2)
    R, Re = fold_ratio(rates["s"], rates["s_err"], g, ge)
    return dict(rates, slope=g, slope_err=ge, R=R, R_err=Re, source=src, curve=curve)
