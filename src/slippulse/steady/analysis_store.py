"""Storage of the analysis of a family (:func:`slippulse.steady.analysis.analyse_family`): per-pulse
attributes and the ``family`` group of the family's HDF5 file, written atomically."""
from __future__ import annotations

import h5py
import numpy as np

from ..core import h5io

#: Per-pulse attributes written by :func:`analyse_family` (name → units).
PULSE_ATTRS = {
    "L_fwhm": "m", "tau_max": "Pa", "tau_m_pulse": "Pa", "total_slip": "m", "delta_ahead": "m",
    "G_bar_max": "J/m^2", "zeta": "1", "zeta_err": "1", "xi_p": "m",
}
#: Arrays of the ``family`` group (name → units).
FAMILY_ARRAYS = {
    "tau_d_ratio": "1", "beta": "1", "c_p": "m/s", "L": "m", "L_tilde": "1", "v_max": "m/s",
    "tau_max": "Pa", "tau_m_pulse": "Pa", "total_slip": "m", "G_bar_max": "J/m^2",
    "zeta": "1", "zeta_err": "1", "max_residual": "1",
}


FAMILY_LONG_NAMES = {
    "beta": "beta = c_p/c_s", "c_p": "pulse speed", "L": "pulse length (FWHM of ln(v/v*+1))",
    "L_tilde": "dimensionless pulse length tau_min^2 L/(mu G_c*)", "v_max": "peak slip rate",
    "tau_max": "peak shear stress", "tau_m_pulse": "minimum shear stress",
    "total_slip": "slip across the pulse", "G_bar_max": "breakdown energy at the tail",
    "zeta": "edge singularity exponent", "zeta_err": "uncertainty of zeta",
    "max_residual": "max |residual|",
}


def _atomic_update(path, fill):
    upd = h5io.atomic_update
    upd(path, fill)


def write_family(path, rows, fam, scaling_window, gc_window):
    """Store the rows of :func:`~slippulse.steady.analysis.analyse_family` (per-pulse attributes
    :data:`PULSE_ATTRS`) and its family results (group ``family``: :data:`FAMILY_ARRAYS`, the
    fits, the mode-II mapping) in the file at ``path``, atomically."""
    def fill(h5):
        for r in rows:
            grp = h5["pulses"][r["label"]]
            for name in PULSE_ATTRS:
                key = "L" if name == "L_fwhm" else name
                grp.attrs[name] = float(r[key])
        if "family" in h5:
            del h5["family"]
        h5io.upgrade_steady(h5)
        g = h5.create_group("family")
        # dimension tau_d_ratio (one entry per pulse, decreasing): the coordinate of every array
        dim = h5io.coordinate(g, "tau_d_ratio", np.array([r["tau_d_ratio"] for r in rows]),
                              units="1", long_name="tau_d/tau_min")
        for name, unit in FAMILY_ARRAYS.items():
            if name != "tau_d_ratio":
                h5io.describe(g.create_dataset(name, data=np.array([r[name] for r in rows],
                                                                   dtype=float)),
                              unit, FAMILY_LONG_NAMES.get(name, name), dims=(dim,))
        h5io.describe(g.create_dataset("label", data=[r["label"] for r in rows],
                                       dtype=h5py.string_dtype()),
                      "1", "pulse group name (pulses/<label>)", dims=(dim,))
        g.attrs["tau_m"] = fam["tau_m"]
        g.attrs["tau_m_units"] = "Pa"
        g.attrs["scaling_window"] = np.array(scaling_window, dtype=float)
        g.attrs["gc_window"] = np.array(gc_window, dtype=float)
        if fam.get("skipped_unconverged"):
            g.attrs["skipped_unconverged"] = ", ".join(fam["skipped_unconverged"])
        if "scaling" in fam:
            s = fam["scaling"]
            for k in ("tau_star", "a_v", "a_G", "tau_star_err", "a_v_err", "a_G_err"):
                g.attrs[k] = s[k]
            g.attrs["scaling_rms"] = s["rms"]
            g.attrs["scaling_n"] = s["n"]
            g.attrs["scaling_cov"] = s["cov"]
            for eq, k in (("beta", "a_v"), ("L", "a_G")):
                if f"scaling_{eq}" in fam:
                    d = fam[f"scaling_{eq}"]
                    for name in ("tau_star", k):
                        g.attrs[f"{eq}_only_{name}"] = d[name]
                        g.attrs[f"{eq}_only_{name}_err"] = d[name + "_err"]
        else:
            g.attrs["scaling_error"] = fam["scaling_error"]
        if "fracture" in fam:
            f = fam["fracture"]
            g.attrs["G_c"] = f["G_c"]
            g.attrs["G_c_err"] = f["G_c_err"]
            g.attrs["G_c_lo"] = f["G_c_lo"]
            g.attrs["G_c_hi"] = f["G_c_hi"]
            g.attrs["G_c_units"] = "J/m^2"
            g.attrs["delta_c"] = f["delta_c"]
            g.attrs["delta_c_units"] = "m"
            g.attrs["G_c_rule"] = (f"the bend of the median G-bar(delta) in log-log: local slope "
                                   f"{f['slope']} (G_c_lo, G_c_hi: slopes {f['band'][0]}, "
                                   f"{f['band'][1]}; G_c_err half their range)")
            g.attrs["G_c_n_curves"] = f["n_curves"]
        else:
            g.attrs["fracture_error"] = fam["fracture_error"]
        m2 = g.create_group("mode_ii")
        for k, d in fam["mode_ii"].items():
            sub = m2.create_group(f"cd_over_cs_{k:.4f}")
            sub.attrs["cd_over_cs"] = k
            h5io.describe(sub.create_dataset("beta", data=d["beta"]), "1",
                          "beta = c_p/c_s of the mode-II pulse", dims=(dim,))
            h5io.describe(sub.create_dataset("L", data=d["L"]), "m",
                          "pulse length of the mode-II pulse", dims=(dim,))

    _atomic_update(path, fill)
