"""The stored spectra of a family as tables: the leading eigenvalue of every pulse on its own grid,
the refined rates s ± s_err with the value of every level of the ladder, and the power law of
s L/c_p near τ_min fitted on the refined values whose sign is resolved
(``slippulse dynamic spectrum-report``; docs/spectrum.md)."""
from __future__ import annotations

import numpy as np

from .law import fit_power_law

#: Windows of τ_d/τ_min (open intervals) of the power-law fits s L/c_p = A (τ_d/τ_min − 1)^n:
#: the approach to τ_min, a narrower one, and one without the deepest pulses (the law holds if
#: the three agree).
FIT_WINDOWS = ((1.0, 1.051), (1.0, 1.041), (1.019, 1.051))
#: Smallest error given to a refined rate in the fits, relative to the rate: a ladder whose
#: levels agree to round-off would otherwise carry all the weight.
MIN_REL_ERR = 1e-3


def family_spectra(path):
    """Stored converged spectra of a file, by decreasing τ_d: list of dicts
    (:func:`.store.read_spectrum`, with ``label``)."""
    from ..core.h5io import labels_in, open_h5
    from .store import read_spectrum
    with open_h5(path) as h5:
        labels = [k for k in labels_in(h5, path) if "spectrum" in h5["pulses"][k]]
    out = []
    for lab in labels:
        o = read_spectrum(path, lab)
        if o is not None and o.get("status") == "converged":
            o["label"] = lab                 # labelled before filtering: a failed pulse shifts none
            out.append(o)
    return sorted(out, key=lambda o: -o["tau_d_ratio"])


def spectrum_rows(spectra, c_s: float) -> list[dict]:
    """One row per pulse of :func:`family_spectra`: label, tau_d_ratio, beta, L (m), s_per_L and
    s (1/s) of the leading eigenvalue on the pulse's own grid (NaN when none is stored),
    im_per_L (its imaginary part per c_p/L), n_unstable, translation_s_per_L (the translation
    eigenvalue, exact 0: the discretisation's error indicator)."""
    rows = []
    for o in spectra:
        lead = o["sigma"][0] if o["sigma"].size else complex(np.nan, np.nan)
        u = float(o["rate_unit_c_over_L"])
        rows.append({"label": o["label"], "tau_d_ratio": float(o["tau_d_ratio"]),
                     "beta": float(o["c_p"]) / c_s, "L": float(o["L"]),
                     "s_per_L": lead.real / u, "s": lead.real, "im_per_L": lead.imag / u,
                     "n_unstable": int(o.get("n_unstable", 0)),
                     "translation_s_per_L": float(o.get("translation_s_per_L", np.nan))})
    return rows


def refined_rows(spectra) -> list[dict]:
    """The pulses whose rate was refined on a ladder of grids (``slippulse steady stability
    --levels K``): label, tau_d_ratio, levels (N of each level), s_levels and translation_levels
    (per c_p/L, each level), s_per_L ± s_err_per_L (the stored value of record), s (1/s)."""
    rows = []
    for o in spectra:
        if "s_per_L" not in o:
            continue
        u = float(o["rate_unit_c_over_L"])
        rows.append({"label": o["label"], "tau_d_ratio": float(o["tau_d_ratio"]),
                     "levels": [int(n) for n in o["refine_n_points"]],
                     "s_levels": [float(s) / u for s in o["refine_s_levels"]],
                     "translation_levels": [float(t) / u for t in o["refine_translation_levels"]],
                     "s_per_L": float(o["s_per_L"]), "s_err_per_L": float(o["s_err_per_L"]),
                     "s": float(o["s_per_L"]) * u})
    return rows


def near_min_fits(refined, windows=FIT_WINDOWS) -> list[dict]:
    """:func:`.law.fit_power_law` of s L/c_p against τ_d/τ_min − 1 in each window, on the refined
    rates whose sign is resolved (s > 2 s_err), each weighted by max(s_err, MIN_REL_ERR·s).
    One dict per window with ≥ 3 such pulses: window, law (:class:`.law.PowerLaw`, errors
    Birge-scaled), pulls (residuals of ln s over their σ, by increasing τ_d)."""
    q = np.array([r["tau_d_ratio"] for r in refined], float)
    s = np.array([r["s_per_L"] for r in refined], float)
    e = np.array([max(r["s_err_per_L"], MIN_REL_ERR * abs(r["s_per_L"])) for r in refined], float)
    out = []
    for lo, hi in windows:
        sel = (q > lo) & (q < hi) & (s > 2 * e)
        if sel.sum() < 3:
            continue
        k = np.argsort(q[sel])
        x, y, err = (q[sel] - 1.0)[k], s[sel][k], e[sel][k]
        law = fit_power_law(x, y, err)
        pulls = (np.log(y) - np.log(law.A * x ** law.n)) / (err / y)
        out.append({"window": (lo, hi), "law": law, "pulls": pulls})
    return out
