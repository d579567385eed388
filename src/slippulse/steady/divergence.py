"""Where L diverges on a deep family: τ̃* and the local exponents (docs/results.md, "Where L
diverges").

The family is read as points (τ_d/τ_min, β, L): the converged pulses of family files and the
grid-checked rows of the tables that ``steady/seeds`` keeps (:func:`read_points`), so a march
chained through seeds is analysed as one family. On them:

* :func:`window_study`: the power laws L = A d^−m_L and 1 − β = B d^m_β, d = τ_d/τ_min − τ̃*
  (:func:`.fits.divergence_fit`, joint and single), and the paper's Eqs. 3–4 refitted for
  (τ̃*, a_v, a_G) (:func:`.fits.scaling_fit`), over windows in τ_d and in L;
* :func:`deepest_decade`: the same fits on the deepest decade of L, τ̃* of record as the centre
  and half-spread of the joint, L-alone and (1 − β)-alone values (no single power law holds, so
  the spread of the fits, not their own 1e−5 errors, is the uncertainty);
* :func:`local_exponents`: d ln L/d ln(1 − β) and d ln L/d ln d against L, centred differences.
"""
from __future__ import annotations

import csv
import dataclasses
import math
import os

import numpy as np

from ..core.errors import UsageError
from .fits import divergence_fit, scaling_fit

#: τ_d/τ_min windows and lower bounds on L (m) of the window study.
Q_WINDOWS = ((1.0, 1.0113), (1.0, 1.0125), (1.0, 1.015), (1.0, 1.02), (1.0, 1.03))
L_MIN = (100.0, 200.0, 400.0, 1000.0, 2000.0)
#: Two τ̃* agree (one pulse, from a file and a table) to this, in τ_d/τ_min.
SAME_Q = 1e-11
#: Fewest pulses in the deepest decade for its fits (5 free constants in the joint fit).
DECADE_MIN = 6
#: The Eqs. 3–4 refit of the deepest decade uses the pulses with L at or above this (m).
EQS34_L_MIN = 2000.0
_TABLE_COLUMNS = ("tau_d_ratio", "beta", "L", "n_points", "continuation", "grid_check_passed")


@dataclasses.dataclass(frozen=True)
class FamilyPoints:
    """The family as points, sorted by decreasing τ_d: τ_d/τ_min ``q``, ``beta``, ``L`` (m),
    grid size ``n_points`` and ``arclength`` (True for the pulses of the deep march)."""

    q: np.ndarray
    beta: np.ndarray
    L: np.ndarray
    n_points: np.ndarray
    arclength: np.ndarray

    def __len__(self):
        return int(self.q.size)


def _table_rows(path):
    """(q, β, L, N, arclength) of the grid-checked rows of one table."""
    if not os.path.isfile(path):
        raise UsageError(f"--table={path!r} is invalid: no such file (a CSV table of a family, "
                         "e.g. steady/seeds/deep_family_*.csv)")
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in _TABLE_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise UsageError(f"--table={path!r} is invalid: no column(s) {', '.join(missing)} "
                             "(a table written by slippulse steady seed --table)")
        rows = []
        for row in reader:
            if row["grid_check_passed"] != "True":
                continue
            try:
                rows.append((float(row["tau_d_ratio"]), float(row["beta"]), float(row["L"]),
                             int(row["n_points"]), row["continuation"] == "arclength"))
            except ValueError:
                raise UsageError(f"--table={path!r} is invalid: row {row.get('label')!r} "
                                 "holds a value that is not a number") from None
    return rows


def _file_rows(path):
    """(q, β, L, N, arclength) of the converged pulses of one family file."""
    from ..core.h5io import list_pulses, read_pulse

    rows = []
    for lab in list_pulses(path):
        pu, _ = read_pulse(path, lab)
        if pu.converged:
            rows.append((pu.tau_d_ratio, pu.beta, pu.L, pu.n_points,
                         pu.extra.get("continuation") == "arclength"))
    return rows


def read_points(files=(), tables=()):
    """The converged pulses of the family ``files`` and the grid-checked rows of the CSV
    ``tables``, one point per τ_d (a table row at the τ_d/τ_min of a pulse already read, to
    :data:`SAME_Q`, is left out: files first, then tables in order)."""
    rows = []
    for src, reader in [(f, _file_rows) for f in files] + [(t, _table_rows) for t in tables]:
        for r in reader(src):
            if not any(abs(r[0] - s[0]) < SAME_Q for s in rows):
                rows.append(r)
    if not rows:
        raise UsageError("no converged pulse in the files and tables given")
    rows.sort(key=lambda r: -r[0])
    q, b, L, n, arc = (np.array(c) for c in zip(*rows))
    return FamilyPoints(q=q.astype(float), beta=b.astype(float), L=L.astype(float),
                        n_points=n.astype(int), arclength=arc.astype(bool))


def _fit(fn, *args, **kw):
    """``fn(*args, **kw)``, or the reason it could not fit (a string)."""
    try:
        return fn(*args, **kw)
    except ValueError as exc:
        return str(exc)


def window_study(pts, params):
    """Fits over the windows of :data:`Q_WINDOWS` (in τ_d/τ_min) and :data:`L_MIN` (L ≥, m).

    Returns a list of (window name, {"both", "L", "beta", "eqs34"}: fit dict or the reason it
    failed)."""
    q, b, L = pts.q, pts.beta, pts.L
    windows = [("q in [%.4f, %.4f]" % w, (q >= w[0]) & (q <= w[1])) for w in Q_WINDOWS]
    windows += [("L >= %g m" % lm, L >= lm) for lm in L_MIN]
    out = []
    for name, sel in windows:
        fits = {qt: _fit(divergence_fit, q[sel], b[sel], L[sel], window=(0.0, 2.0),
                         quantities=qt) for qt in ("both", "L", "beta")}
        fits["eqs34"] = _fit(scaling_fit, q[sel], b[sel], L[sel] / params.L_Gc, params,
                             window=(0.0, 2.0))
        out.append((name, fits))
    return out


def deepest_decade(pts, params):
    """Fits on the pulses with L ≥ max L/10: the joint and single power laws, the Eqs. 3–4
    refit on L ≥ :data:`EQS34_L_MIN`, and τ̃* of record with its uncertainty.

    Returns
    -------
    dict
        n, L_lo, L_hi; fits ("both", "L", "beta"; "eqs34": a fit dict or the reason it failed);
        tau_star, tau_star_err: the centre and half-range of the three power-law τ̃*.

    Raises
    ------
    ValueError
        Fewer than :data:`DECADE_MIN` pulses in the decade.
    """
    deep = pts.L >= pts.L.max() / 10.0
    if deep.sum() < DECADE_MIN:
        raise ValueError(f"the deepest decade of L holds {int(deep.sum())} pulses; its fits need "
                         f">= {DECADE_MIN}")
    q, b, L = pts.q[deep], pts.beta[deep], pts.L[deep]
    fits = {qt: divergence_fit(q, b, L, window=(0.0, 2.0), quantities=qt)
            for qt in ("both", "L", "beta")}
    big = L >= EQS34_L_MIN
    fits["eqs34"] = _fit(scaling_fit, q[big], b[big], L[big] / params.L_Gc, params,
                         window=(0.0, 2.0))
    ts = [fits[k]["tau_star"] for k in ("both", "L", "beta")]
    return {"n": int(deep.sum()), "L_lo": float(L.min()), "L_hi": float(L.max()), "fits": fits,
            "tau_star": 0.5 * (max(ts) + min(ts)), "tau_star_err": 0.5 * (max(ts) - min(ts))}


def local_exponents(pts, tau_star):
    """Centred local exponents at the inner pulses, sorted by L.

    Returns
    -------
    dict of arrays
        L, q (at the inner pulses); r = d ln L/d ln(1 − β) (positive: L grows as β → 1);
        m = d ln L/d ln d, d = q − ``tau_star`` (NaN where a neighbour lies at or below
        ``tau_star``); s = −dq/d ln L.
    """
    if len(pts) < 3:
        raise ValueError(f"local exponents need >= 3 pulses; found {len(pts)}")
    o = np.argsort(pts.L)
    lnL, lnb, q = np.log(pts.L[o]), np.log(1.0 - pts.beta[o]), pts.q[o]
    d = q - tau_star
    with np.errstate(divide="ignore", invalid="ignore"):
        m = np.where((d[2:] > 0) & (d[:-2] > 0),
                     -(lnL[2:] - lnL[:-2]) / np.log(np.abs(d[2:] / d[:-2])), np.nan)
        r = -(lnL[2:] - lnL[:-2]) / (lnb[2:] - lnb[:-2])
        s = -(q[2:] - q[:-2]) / (lnL[2:] - lnL[:-2])
    return {"L": pts.L[o][1:-1], "q": q[1:-1], "r": r, "m": m, "s": s}


def nearest(loc, L, key):
    """``loc[key]`` at the inner pulse whose L is nearest ``L`` (m), and that pulse's L."""
    k = int(np.argmin(np.abs(np.log(loc["L"] / L))))
    return float(loc[key][k]), float(loc["L"][k])


def fit_text(f):
    """One fit dict of :func:`divergence_fit` or :func:`scaling_fit` as a line, with errors."""
    if isinstance(f, str):
        return f"no fit: {f}"
    head = (f"n={f['n']} tau_star={f['tau_star']:.5f} ± {f['tau_star_err']:.5f}"
            + (" (at bound)" if f.get("at_bound") else ""))
    if "a_v" in f:
        return head + (f" a_v={f['a_v']:.3f} ± {f['a_v_err']:.3f} a_G={f['a_G']:.3f} ± "
                       f"{f['a_G_err']:.3f} rms={f['rms']:.1e}")
    parts = [head]
    if math.isfinite(f["m_L"]):
        parts.append(f"m_L={f['m_L']:.3f} ± {f['m_L_err']:.3f}")
    if math.isfinite(f["m_beta"]):
        parts.append(f"m_beta={f['m_beta']:.3f} ± {f['m_beta_err']:.3f}")
    return " ".join(parts + [f"rms={f['rms']:.1e}"])
