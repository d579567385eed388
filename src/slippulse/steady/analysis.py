"""What the paper measures on a steady pulse and on the family of pulses (Pomyalov et al., PRE 2023):
the drivers. :func:`analyse_pulse` gathers the per-pulse measures (:mod:`.measures`) of one pulse,
:func:`analyse_family` those of every pulse of a family file and the family fits (:mod:`.fits`),
and stores them (:mod:`.analysis_store`); :func:`~.analysis_table.format_table` prints them.

The measures, fits, storage and table are re-exported here (``analysis.pulse_length`` etc.).
"""
from __future__ import annotations

import math

import numpy as np

from ..core import h5io
from .analysis_store import FAMILY_ARRAYS, FAMILY_LONG_NAMES, PULSE_ATTRS, write_family
from .analysis_table import format_table
from .fits import (GC_SLOPE, GC_WINDOW, SCALING_WINDOW, beta_parametrised_fit, divergence_fit,
                   fracture_energy, scaling_fit, scaling_law)
from .measures import (breakdown_energy, edge_singularity, edge_structure, ln_one_minus_g,
                       profile_distance, pulse_length, slip_profile)

__all__ = ["FAMILY_ARRAYS", "FAMILY_LONG_NAMES", "GC_SLOPE", "GC_WINDOW", "PULSE_ATTRS",
           "SCALING_WINDOW", "SUPPORT_DEPTH", "SUPPORT_MIN", "analyse_family", "analyse_pulse",
           "beta_parametrised_fit", "breakdown_energy", "divergence_fit", "edge_singularity",
           "edge_structure", "format_table", "fracture_energy", "ln_one_minus_g",
           "profile_distance", "pulse_length", "scaling_fit", "scaling_law", "slip_profile",
           "support"]


# --------------------------------------------------------------------------- drivers
def analyse_pulse(pulse, params, tau_m=None, edge_window=None):
    """Scalar measures of one pulse.

    Parameters
    ----------
    pulse : h5io.Pulse
    params : Parameters
    tau_m : float, optional
        Reference stress for Ḡ and ζ, Pa; default: this pulse's own minimum of τ.
    edge_window : (float, float), optional
        Passed to :func:`edge_singularity`.

    Returns
    -------
    dict
        label, tau_d_ratio, beta, c_p (m/s), L (FWHM, m), L_tilde, xi_left, xi_right (m),
        L_solver (the solver's stored L, m), v_max (m/s), xi_vmax (m), tau_max (Pa), xi_taumax (m),
        tau_m_pulse (min τ, Pa), tau_m_used (Pa), total_slip (m), delta_ahead (m, slip accumulated
        ahead of the stress peak), G_bar_max (J/m²), max_residual, converged, and the edge fit
        zeta, zeta_err, xi_p (NaN when the fit is impossible, with ``zeta_note`` saying why).
    """
    p = pulse
    L, xl, xr = pulse_length(p.xi, p.v, params.v_star)
    tau_m_pulse = float(np.min(p.tau))
    tm = tau_m_pulse if tau_m is None else float(tau_m)
    delta, G = breakdown_energy(p.xi, p.v, p.tau, p.v_stick, p.beta, params.c_s, tm)
    iv, it = int(np.argmax(p.v)), int(np.argmax(p.tau))
    row = {
        "label": p.label, "tau_d_ratio": float(p.tau_d_ratio), "beta": float(p.beta),
        "c_p": float(p.beta * params.c_s), "L": float(L), "L_tilde": float(L / params.L_Gc),
        "xi_left": float(xl), "xi_right": float(xr), "L_solver": float(p.L),
        "v_max": float(p.v[iv]), "xi_vmax": float(p.xi[iv]),
        "tau_max": float(p.tau[it]), "xi_taumax": float(p.xi[it]),
        "tau_m_pulse": tau_m_pulse, "tau_m_used": tm,
        "total_slip": float(delta[0]), "delta_ahead": float(delta[it]),
        "G_bar_max": float(np.max(G)),
        "max_residual": float(p.max_residual), "converged": bool(p.converged),
    }
    try:
        es = edge_singularity(p.xi, p.v, p.tau, tm, params.c_s, params.sigma,
                              window=edge_window, L=L)
        note = ""
        if not np.isfinite(es["zeta_err"]):      # say which part of the error is missing
            note = ("no variant of the fit window (r_min, r_max scaled by 0.5-2 with "
                    "r_max/r_min >= 3) lies on the grid" if not np.isfinite(es["zeta_err_window"])
                    else "the fit's covariance is singular")
        row.update(zeta=es["zeta"], zeta_err=es["zeta_err"], xi_p=es["xi_p"],
                   zeta_at_bound=es["at_bound"], zeta_note=note)
    except (ValueError, np.linalg.LinAlgError) as exc:
        row.update(zeta=float("nan"), zeta_err=float("nan"), xi_p=float("nan"),
                   zeta_at_bound=False, zeta_note=str(exc))
    return row


#: The family results that need pulses near τ_*: (name in the family dict, the error key, what).
#: The scaling fit and G_c are read off the pulses down to τ_d/τ_min = SUPPORT_DEPTH (the
#: paper's family ends there; its Fig. 4 curves and Eq. 3-4 constants come from them). A family
#: that stops above it, or holds fewer than SUPPORT_MIN pulses in the window, gets the reason
#: instead of the number (a 1.2 -> 1.02 family would print G_c = 0.0047 for the paper's 0.6).
SUPPORT_DEPTH = 1.015
SUPPORT_MIN = {"scaling": 5, "fracture": 3}


def support(ratios, window, what, need_min) -> str | None:
    """Why the converged pulses at ``ratios`` cannot support the family result ``what`` fitted
    over ``window`` (None: they can)."""
    inside = [r for r in ratios if window[0] <= r <= window[1]]
    if len(inside) < need_min:
        return (f"not supported by this family: {what} needs >= {need_min} converged pulses with "
                f"tau_d/tau_min in [{window[0]}, {window[1]}], it has {len(inside)}")
    if min(inside) > SUPPORT_DEPTH + 1e-9:
        return (f"not supported by this family: {what} needs pulses down to tau_d/tau_min = "
                f"{SUPPORT_DEPTH} (near tau_*), its deepest is {min(inside):.4f} "
                f"(slippulse steady family --to {SUPPORT_DEPTH})")
    return None


def analyse_family(path, write=True, scaling_window=SCALING_WINDOW, gc_window=GC_WINDOW,
                   skip=(), gc_slope=GC_SLOPE, cd_over_cs=None):
    """Analyse every pulse of a family file (but the labels ``skip``); optionally store the
    results in it. The scaling fit and G_c are left out, with the reason, where the family cannot
    support them (:func:`support`).

    Parameters
    ----------
    path : str
        Family HDF5 file (``pulses/tdX.XXXX`` groups).
    write : bool
        Add per-pulse attributes (:data:`PULSE_ATTRS`) and a ``family`` group, atomically (copy to
        a temporary file in the same directory, modify, ``os.replace``).
    scaling_window, gc_window : (float, float)
        τ_d/τ_min windows of the scaling fit and of the G_c/δ_c analysis.
    gc_slope : float
        The local slope of the median Ḡ(δ) in log-log that marks its bend (:func:`fracture_energy`).
    cd_over_cs : sequence of float, optional
        c_d/c_s values of the mode-II mapping (default ``modeii.CD_OVER_CS``).

    Returns
    -------
    list of dict
        One row per pulse (:func:`analyse_pulse`), by decreasing τ_d. The family-level results
        are attached to the first row under ``"family"`` (dict: tau_m, scaling, fracture, mode_ii).

    Notes
    -----
    τ_m (used for Ḡ and ζ of every pulse) is min τ(ξ) of the pulse with the smallest τ_d: the
    paper's "minimum of τ(ξ) for τ_d close to τ_*", the value the minima converge to (Fig. 2b).
    (Pulses far from τ_min can dip slightly lower, by ~1e-4 τ_min; their Ḡ then has tiny
    negative increments there.)
    Failures of a family-level fit are recorded as the attribute ``*_error`` instead of raising;
    the family fits (scaling law, G_c) use the pulses with ``converged`` True only.
    """
    from . import modeii

    if cd_over_cs is None:
        cd_over_cs = modeii.CD_OVER_CS
    labels = [lab for lab in h5io.list_pulses(path) if lab not in set(skip)]
    if not labels:
        raise h5io.SchemaError(f"{path}: no pulses")
    pulses = []
    params = None
    for lab in labels:
        p, prm = h5io.read_pulse(path, lab)
        params = prm
        pulses.append(p)
    tau_m = float(np.min(pulses[-1].tau))        # smallest τ_d (list is by decreasing τ_d)
    rows = []
    for p in pulses:
        try:
            rows.append(analyse_pulse(p, params, tau_m=tau_m))
        except ValueError as exc:
            raise h5io.SchemaError(f"{path}: pulse {p.label} cannot be analysed: {exc}") from None
    fam = {"tau_m": tau_m}
    x = np.array([r["tau_d_ratio"] for r in rows])
    beta = np.array([r["beta"] for r in rows])
    Lt = np.array([r["L_tilde"] for r in rows])
    conv = np.array([r["converged"] for r in rows], dtype=bool)   # fits use converged pulses only
    try:
        fam["scaling"] = scaling_fit(x[conv], beta[conv], Lt[conv], params, window=scaling_window)
    except ValueError as exc:
        fam["scaling_error"] = str(exc)
    for eq in ("beta", "L"):          # single-equation diagnostics (does one τ̃* fit both?)
        try:
            fam[f"scaling_{eq}"] = scaling_fit(x[conv], beta[conv], Lt[conv], params,
                                              window=scaling_window, equations=eq)
        except ValueError:
            pass
    sel = [p for p in pulses
           if p.converged and gc_window[0] <= p.tau_d_ratio <= gc_window[1]]
    try:
        curves = [breakdown_energy(p.xi, p.v, p.tau, p.v_stick, p.beta, params.c_s, tau_m)
                  for p in sel]
        fam["fracture"] = fracture_energy(curves, slope=gc_slope)
    except ValueError as exc:
        fam["fracture_error"] = str(exc)
    for key, what, window in (("scaling", "the scaling fit (Eqs. 3-4)", scaling_window),
                              ("fracture", "G_c (the bend of the G-bar curves)", gc_window)):
        why = support(x[conv], window, what, SUPPORT_MIN[key])
        if why:
            for k in ((key, "scaling_beta", "scaling_L") if key == "scaling" else (key,)):
                fam.pop(k, None)
            fam[f"{key}_error"] = why
    if skip:
        fam["skipped_unconverged"] = list(skip)
    fam["mode_ii"] = {}
    L = np.array([r["L"] for r in rows])
    for k in cd_over_cs:
        b2, L2 = modeii.map_family(beta, L, k)
        fam["mode_ii"][float(k)] = {"beta": b2, "L": L2}
    rows[0]["family"] = fam
    if write:
        write_family(path, rows, fam, scaling_window, gc_window)
    return rows


# --------------------------------------------------------------------------- referee checks
def slip_criterion(pulses, params, rates=None):
    """Brantut, Garagash & Noda (2019)'s criterion along a family: a steady pulse is unstable
    where its total slip b decreases with the load, db/dτ_d < 0.

    Parameters
    ----------
    pulses : sequence of h5io.Pulse
        Converged pulses of one family (any order; sorted by β, monotone along the main family).
    rates : mapping τ_d/τ_min → (s L/c_p, s_err L/c_p), optional
        Growth rates of the spectrum (e.g. the rates of record), each given to the nearest pulse
        within 5e-7 in τ_d (the rounding of a label).

    Returns
    -------
    list of dict, one per pulse by rising β: label, tau_d_ratio, beta, L (m), slip (b, m: the
    slip across the whole domain, :func:`slip_profile` at its back end), db_dq (m, d b/d(τ_d/τ_min)
    by second-order differences along the family, NaN at the ends of a pair), predicted
    ('unstable' where db/dq < 0), s, s_err (or NaN), s_sign ('+', '-' or 'unresolved' when
    |s| < 2 s_err, None without a rate), agree (None where either is missing or unresolved).
    """
    ps = sorted(pulses, key=lambda p: p.beta)
    q = np.array([p.tau_d_ratio for p in ps], float)
    b = np.array([float(slip_profile(p.xi, p.v, p.v_stick, p.beta, params.c_s)[0]) for p in ps])
    db = np.full(q.size, np.nan)
    for i in range(q.size):
        lo, hi = max(i - 1, 0), min(i + 1, q.size - 1)
        if hi - lo == 2:
            # second-order derivative on a non-uniform stencil (Lagrange through three points)
            x0, x1, x2 = q[lo], q[i], q[hi]
            db[i] = (b[lo] * (x1 - x2) / ((x0 - x1) * (x0 - x2))
                     + b[i] * (2 * x1 - x0 - x2) / ((x1 - x0) * (x1 - x2))
                     + b[hi] * (x1 - x0) / ((x2 - x0) * (x2 - x1)))
        elif hi > lo and q[hi] != q[lo]:
            db[i] = (b[hi] - b[lo]) / (q[hi] - q[lo])
    # each rate goes to the nearest pulse within the rounding of a 6-decimal label
    matched = {}
    for qq, (sv, ev) in (rates or {}).items():
        i = int(np.argmin(np.abs(q - qq)))
        if abs(q[i] - qq) <= 5.01e-7:
            matched[i] = (float(sv), float(ev))
    rows = []
    for i, p in enumerate(ps):
        s, se = matched.get(i, (math.nan, math.nan))
        sign = None
        if math.isfinite(s):
            sign = "unresolved" if abs(s) < 2 * se else ("+" if s > 0 else "-")
        pred = None if not math.isfinite(db[i]) else ("unstable" if db[i] < 0 else "stable")
        agree = None
        if pred is not None and sign in ("+", "-"):
            agree = (pred == "unstable") == (sign == "+")
        rows.append({"label": p.label, "tau_d_ratio": float(p.tau_d_ratio), "beta": float(p.beta),
                     "L": float(p.L), "slip": float(b[i]), "db_dq": float(db[i]),
                     "predicted": pred, "s": s, "s_err": se, "s_sign": sign, "agree": agree})
    return rows


#: The paper's own range of τ_d/τ_min, where its constants of Eqs. 3–4 were fitted (its Fig. 3).
PAPER_WINDOW = (1.015, 1.2)


def paper_range_fit(path, window=PAPER_WINDOW):
    """Eqs. 3–4 fitted over the paper's range on the converged pulses of a family file (joint and
    single-equation fits, :func:`scaling_fit`: keys 'both', 'beta', 'L'), with the paper's
    constants ('paper') and the rms of the log residuals of β and L̃ they leave on the same
    pulses ('paper_rms')."""
    from ..core.reference import paper_scaling
    x, b, Lt = [], [], []
    params = None
    for lab in h5io.list_pulses(path):
        p, params = h5io.read_pulse(path, lab)
        if p.converged:
            x.append(p.tau_d_ratio)
            b.append(p.beta)
            Lt.append(p.L / params.L_Gc)
    out = {"paper": dict(paper_scaling())}
    for eq in ("both", "beta", "L"):
        out[eq] = scaling_fit(x, b, Lt, params, window=window, equations=eq)
    # the paper's constants on the same pulses: rms of the log residuals of β and L̃ together
    x, b, Lt = np.asarray(x), np.asarray(b), np.asarray(Lt)
    sel = (x >= window[0]) & (x <= window[1])
    pp = out["paper"]
    bm, Lm = scaling_law(x[sel], pp["tau_star"], pp["a_v"], pp["a_G"], params)
    res = np.concatenate([np.log(bm / b[sel]), np.log(Lm / Lt[sel])])
    out["paper_rms"] = float(np.sqrt(np.mean(res ** 2)))
    return out


def edge_record(path, label=None):
    """ζ (edge singularity, joint fit) and Ḡ_max of the pulse ``label`` (default: the smallest
    τ_d) of a family file, with τ_m the minimum of τ of the smallest-τ_d pulse (as
    :func:`analyse_family`). Returns the :func:`analyse_pulse` row."""
    labels = h5io.list_pulses(path)
    deepest, params = h5io.read_pulse(path, labels[-1])
    p = deepest if label is None else h5io.read_pulse(path, label)[0]
    return analyse_pulse(p, params, tau_m=float(np.min(deepest.tau)))
