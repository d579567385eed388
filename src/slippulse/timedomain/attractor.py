"""The steady line as attractor, measured in time (docs/stability.md §4).

* :func:`mode_pairs`, :func:`pair_response`, :func:`pair_analysis`: an eigenmode-seeded ±ε pair
  of the SBI against its mode: the growth rate, and the antisymmetric front displacement and
  length change per unit antisymmetric change of v_max, against the mode's first-order
  prediction (:func:`.eigenmode.front_response`);
* :func:`departure_fraction`, :func:`sbi_departures`: the part of the change of ln c_p that
  leaves the steady line, f = 1 − m_line δln L/δln c (0 along the line, 1 at fixed L), as the
  mode predicts it (:func:`.eigenmode.pulse_overlap`) and as a pair measures it;
* :func:`line_departure`, :func:`base_pair_departures`: how far a run strays from the steady
  line, |c_p/c_p⁰(L) − 1| along its whole trajectory (``slippulse dynamic growth-report``);
* :func:`write_overlap_csv`, :func:`read_overlap_csv`: the rows of
  :func:`.eigenmode.family_overlaps` as a table.
"""
from __future__ import annotations

import csv
import glob
import math
import os

import numpy as np

from ..core.atomic import replacing_open
from .eigenmode import leading_mode, front_response, local_neighbours, pulse_overlap
from .perturbation import line_deviation, pair_rows, read_series, scan_rows, smoothed_c_p

#: Bound of the linear regime of a pair: either run's |v_max/v_max⁰ − 1| ≤ D_MAX
#: (as :func:`.perturbation.pair_growth`).
D_MAX = 0.03
#: Columns of the overlap table (:func:`write_overlap_csv`).
OVERLAP_COLUMNS = ("label", "tau_d_ratio", "s_per_L", "overlap", "overlap_y", "dL_over_L",
                   "dc_over_c", "direction", "line_slope", "departure_fraction", "angle_deg")


def mode_pairs(scan_dir: str) -> list[tuple[tuple, dict, dict]]:
    """The eigenmode-seeded ±ε pairs (perturbation ``mode`` or ``mode_front``) among the run
    files of a scan directory: (key, + series, − series), key = (steady file, label, Δx, |ε|,
    ahead, behind, perturbation). Runs of other perturbations and unpaired runs are left out."""
    runs: dict = {}
    for f in sorted(glob.glob(os.path.join(scan_dir, "*.h5"))):
        if os.path.basename(f).startswith("summary"):
            continue
        s = read_series(f)
        a = s["attrs"]
        if str(a.get("perturbation")) not in ("mode", "mode_front"):
            continue
        key = (str(a["steady_file"]), str(a["label"]), float(a["dx"]), abs(float(a["eps"])),
               float(a["ahead"]), float(a["behind"]), str(a["perturbation"]))
        runs.setdefault(key, {})[1 if float(a["eps"]) > 0 else -1] = s
    return [(k, g[1], g[-1]) for k, g in runs.items() if 1 in g and -1 in g]


def pair_response(plus: dict, minus: dict, d_max: float = D_MAX) -> dict:
    """The antisymmetric response of a ±ε pair (``read_series`` dicts) over its linear regime
    (from the second sample until either run's |v_max error| exceeds ``d_max``).

    r = (v_max error⁺ − v_max error⁻)/2; rX, rL the same for the front position and L/L⁰. The
    symmetric (quadratic) parts cancel. Returns s_fit_all and s_fit_first_third (the slope of
    ln|r| over the regime and over its first third, per pulse length: × L⁰/c_p⁰), k_front (m)
    and k_length (1), the least-squares amplitude ratios rX/r and rL/r over the regime's second
    half (the front position carries sub-cell noise early), and d_end (L⁰ travelled at the
    regime's end). Raises ValueError when the regime holds fewer than 3 samples."""
    a = plus["attrs"]
    n = min(plus["t"].size, minus["t"].size)
    t = plus["t"][:n]
    conv = float(a["L"]) / float(a["c_p"])

    def anti(name):
        return 0.5 * (plus[name][:n] - np.interp(t, minus["t"], minus[name]))

    r = anti("v_max_error")
    big = np.maximum(np.abs(plus["v_max_error"][:n]),
                     np.abs(np.interp(t, minus["t"], minus["v_max_error"])))
    end = np.nonzero(big > d_max)[0]
    i1 = int(end[0]) if end.size else n
    sel = np.arange(1, i1)
    if sel.size < 3:
        raise ValueError(f"the linear regime (|v_max error| <= {d_max:g}) holds {sel.size} "
                         "samples after the first: no rate")
    s_all = np.polyfit(t[sel], np.log(np.abs(r[sel])), 1)[0] * conv
    first = sel[: max(5, sel.size // 3)]
    s_first = np.polyfit(t[first], np.log(np.abs(r[first])), 1)[0] * conv
    late = sel[sel.size // 2:]
    norm = float(np.sum(r[late] ** 2))
    k_front = (float(np.sum(anti("x_front")[late] * r[late]) / norm) if "x_front" in plus
               else math.nan)
    k_length = float(np.sum((anti("L") / float(a["L"]))[late] * r[late]) / norm)
    return {"s_fit_all": float(s_all), "s_fit_first_third": float(s_first),
            "k_front": k_front, "k_length": k_length, "d_end": float(t[i1 - 1] / conv)}


def pair_analysis(key: tuple, plus: dict, minus: dict, d_max: float = D_MAX) -> dict:
    """:func:`pair_response` of one :func:`mode_pairs` entry against its eigenmode (the stored
    spectrum of the steady file the runs were seeded from): the rates relative to the eigenvalue,
    and the change of c_p and of L per unit relative change of v_max, measured
    (dc_per_dv_sbi = σ k_front/c_p, the front's displacement growing as e^{σt};
    dL_per_dv_sbi = k_length) and predicted (:func:`.eigenmode.front_response`)."""
    from ..core.h5io import read_pulse
    steady, label, dx, eps = key[:4]
    g = pair_response(plus, minus, d_max)
    pulse, params = read_pulse(steady, label)
    mode = leading_mode(pulse, params, path=steady, compute=False)
    fr = front_response(mode, pulse, params.v_star)
    sig = mode.sigma.real
    return {"label": label, "steady": os.path.basename(steady), "tau_d_ratio": pulse.tau_d_ratio,
            "dx": dx, "eps": eps, "period_L": key[4] + key[5], "perturbation": key[6],
            "eigen_s_per_L": mode.s_per_L, "s_fit_all": g["s_fit_all"],
            "s_fit_first_third": g["s_fit_first_third"], "d_end": g["d_end"],
            "rel_all": g["s_fit_all"] / mode.s_per_L - 1,
            "rel_first": g["s_fit_first_third"] / mode.s_per_L - 1,
            "dc_per_dv_sbi": sig * g["k_front"] / pulse.c_p,
            "dc_per_dv_mode": float(fr["dc_over_c"] / fr["dvmax_over_vmax"]),
            "dL_per_dv_sbi": g["k_length"],
            "dL_per_dv_mode": float(fr["dL_over_L"] / fr["dvmax_over_vmax"])}


def departure_fraction(line_slope: float, dlnL: float, dlnc: float) -> float:
    """f = 1 − m_line δln L/δln c: the part of a change (δln L, δln c) of a pulse that leaves the
    steady line of slope m_line = d ln c_p/d ln L (0 along it, 1 at fixed L; NaN when δln c = 0)."""
    if not dlnc or not math.isfinite(dlnc):
        return math.nan
    return 1.0 - line_slope * dlnL / dlnc


def sbi_departures(pair_dirs, rows=(), local_h: float = 2e-3) -> list[dict]:
    """The departure fraction each eigenmode-seeded pair of ``pair_dirs`` measures (with
    :func:`pair_analysis`'s measured δln L, δln c) and the mode's, against the steady line's slope
    at its pulse: that of the :func:`.eigenmode.family_overlaps` row at the same τ_d in ``rows``,
    else from the pulses at τ_d ± local_h solved on its grid (seconds per pulse)."""
    from ..core.h5io import read_pulse
    out = []
    for d in pair_dirs:
        for key, p, m in mode_pairs(d):
            a = pair_analysis(key, p, m)
            pulse, params = read_pulse(key[0], key[1])
            same = [r for r in rows if abs(float(r["tau_d_ratio"]) - pulse.tau_d_ratio) < 1e-9]
            if same:
                slope, f_mode = float(same[0]["line_slope"]), float(same[0]["departure_fraction"])
            else:
                mode = leading_mode(pulse, params, path=key[0], compute=False)
                ov = pulse_overlap(pulse, mode, local_neighbours(pulse, params, local_h),
                                   params.v_star)
                slope, f_mode = ov["line_slope"], ov["departure_fraction"]
            out.append({"label": key[1], "steady": key[0], "eps": key[3],
                        "tau_d_ratio": pulse.tau_d_ratio, "line_slope": slope,
                        "departure_fraction": departure_fraction(slope, a["dL_per_dv_sbi"],
                                                                 a["dc_per_dv_sbi"]),
                        "departure_fraction_mode": f_mode})
    return out


def line_departure(series: dict, curve: np.ndarray, skip: float = 0.1) -> dict:
    """How far one run (``read_series``) strays from the steady line c_p⁰(L) (``curve`` of
    :func:`.perturbation.steady_curve`): |c_p/c_p⁰(L) − 1| of its samples past ``skip`` L⁰ of
    travel (the seed's start-up), c_p smoothed over 5 samples (:func:`.perturbation.smoothed_c_p`;
    the two samples at each end, where the smoothing is one-sided, left out).

    Returns L_min, L_max (m), beta_min, beta_max, median and max of |c_p/c_p⁰(L) − 1| (NaN when
    no sample lies in the line's L range) and fraction (of the samples in that range)."""
    cs = float(series["attrs"]["c_p"]) / float(series["attrs"]["beta"])
    cp = smoothed_c_p(series)
    i = np.arange(cp.size)
    keep = (series["distance"] >= skip) & (i >= 2) & (i < cp.size - 2)
    if not keep.any():
        raise ValueError(f"the run holds no sample past {skip:g} L of travel")
    L = series["L"][keep]
    dev = np.abs(line_deviation(L, cp[keep], curve))
    ok = np.isfinite(dev)
    return {"L_min": float(L.min()), "L_max": float(L.max()),
            "beta_min": float(cp[keep].min() / cs), "beta_max": float(cp[keep].max() / cs),
            "median": float(np.median(dev[ok])) if ok.any() else math.nan,
            "max": float(np.max(dev[ok])) if ok.any() else math.nan,
            "fraction": float(ok.mean())}


def base_pair_departures(scan, curve: np.ndarray | None = None) -> dict | None:
    """:func:`line_departure` of the + and − run of a scan's base pair (its first finished ±ε
    pair, in case order: ``slippulse dynamic growth-report``'s base): tau_d_ratio, eps, plus,
    minus (the medians). ``curve``: the steady line (default: that of the steady file the pair
    was seeded from). None when the scan has no finished pair."""
    from .perturbation import steady_curve
    pairs = pair_rows(scan_rows(scan))
    if not pairs:
        return None
    rp, rm = pairs[0]
    if curve is None:
        curve = steady_curve(str(rp["steady"]))
    return {"tau_d_ratio": float(rp["tau_d_ratio"]), "eps": abs(float(rp["eps"])),
            "plus": line_departure(read_series(rp["file"]), curve)["median"],
            "minus": line_departure(read_series(rm["file"]), curve)["median"]}


def write_overlap_csv(rows: list[dict], path: str) -> str:
    """The rows of :func:`.eigenmode.family_overlaps` as a CSV table (:data:`OVERLAP_COLUMNS`),
    written atomically. Returns ``path``."""
    with replacing_open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(OVERLAP_COLUMNS), extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (r[k] if k == "label" else float(r[k])) for k in OVERLAP_COLUMNS})
    return path


def read_overlap_csv(path: str) -> list[dict]:
    """The rows of a :func:`write_overlap_csv` table, by increasing τ_d. Raises ValueError when
    a column is missing."""
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        missing = [k for k in OVERLAP_COLUMNS if k not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: not an overlap table (columns {missing} missing)")
        rows = [{k: (r[k] if k == "label" else float(r[k])) for k in OVERLAP_COLUMNS}
                for r in reader]
    return sorted(rows, key=lambda r: r["tau_d_ratio"])
