"""Storage of a pulse's stability spectrum: the ``spectrum`` subgroup of its pulse group (xarray-
readable; written atomically), and its reader."""
from __future__ import annotations

import numpy as np


SPECTRUM_GROUP = "spectrum"
MODE_FIELDS = {"delta": ("m", "slip perturbation delta_1 (mode normalised: max |lnv_1| = 1)"),
               "V": ("m/s", "slip-rate perturbation V_1"),
               "phi": ("s", "state perturbation phi_1"),
               "lnv": ("1", "perturbation of ln(v/v* + 1)")}


#: units of the attributes that have them (written as ``<name>_units``)
ATTR_UNITS = {"leading_sigma_real": "1/s", "leading_sigma_imag": "1/s",
              "rate_unit_c_over_L": "1/s", "translation_sigma": "1/s", "wall_time": "s",
              "s": "1/s", "s_err": "1/s", "refine_s_levels": "1/s",
              "refine_imag_levels": "1/s", "refine_translation_levels": "1/s",
              "refine_s_extrapolated": "1/s", "refine_translation_extrapolated": "1/s",
              "refine_translation_err": "1/s", "refine_rate_unit_levels": "1/s"}


def spectrum_attrs(res) -> dict:
    """The scalars of a :class:`~slippulse.spectrum.pulse.PulseSpectrum`: its status, leading and
    neutral eigenvalues, cost and failures."""
    lead = res.leading
    return {"status": res.status, "message": res.message,
            "n_eigenvalues": int(res.sigmas.size), "n_unstable": res.n_unstable,
            "leading_sigma_real": lead.real, "leading_sigma_imag": lead.imag,
            "leading_s_per_L": lead.real / res.rate_unit, "rate_unit_c_over_L": res.rate_unit,
            "uniform_slip_backward_error": float(res.neutral[0].real),
            "translation_sigma": float(res.neutral[1].real),
            "translation_s_per_L": float(res.neutral[1].real / res.rate_unit),
            "translation_mode_error": float(res.translation_error),
            "n_points": res.n_points, "wall_time": res.wall_time,
            "newton_iterations": res.newton_iterations, "failures": "; ".join(res.failures),
            "leading_from": res.leading_from}


def refine_attrs(ref) -> dict:
    """The leading growth rate of record (finest nested level, error = last correction), its
    levels, and the check against a known answer (σ_t, exactly 0, extrapolated as s is)."""
    out = {"refine_status": ref.status, "refine_message": ref.message,
           "refine_n_points": np.asarray(ref.n_points, dtype="i8"),
           "refine_s_levels": np.asarray(ref.s_levels, dtype=float),
           "refine_imag_levels": np.asarray(ref.imag_levels, dtype=float),
           "refine_translation_levels": np.asarray(ref.translation_levels, float),
           "refine_rate_unit_levels": np.asarray(ref.unit_levels, float),       # c_p/L
           "refine_pinned": int(ref.pinned), "refine_order": ref.order,
           "refine_rule": ref.rule, "refine_level_ratio": float(ref.ratio),
           "refine_target_s_err_per_L": float(ref.target),
           "refine_target_met": int(ref.target_met),
           "refine_s_extrapolated": float(ref.s_extrapolated),
           "refine_translation_extrapolated": float(ref.translation_extrapolated),
           "refine_translation_err": float(ref.translation_err)}
    if ref.status == "converged":
        out["s"], out["s_err"] = ref.s, ref.s_err
        out["s_per_L"], out["s_err_per_L"] = ref.per_length()
        out["sign_resolved"] = int(ref.sign_resolved)
    return out


def count_attrs(cnt) -> dict:
    """The argument-principle count: its status, box, cost and winding, and the count itself
    where it converged."""
    out = {"count_status": cnt.status, "count_message": cnt.message,
           "count_box_c_over_L": np.asarray(cnt.box, dtype=float),
           "count_evaluations": int(cnt.n_evals), "count_winding": float(cnt.winding),
           "count_max_step_rad": float(cnt.max_step),
           "count_max_reach_rad": float(cnt.reach)}                # nan: walk without M′
    if cnt.count is not None:
        out["count"] = int(cnt.count)
        located = np.asarray(cnt.located, complex)
        out["count_located_real"] = located.real      # the polished zeros in the box, c_p/L
        out["count_located_imag"] = located.imag
    return out


def _mode_axis(g, grp_p, res):
    """(the xi coordinate of the modes, the slice of the modes' nodes that lies on it): the
    pulse's own xi, its nodes picked from a nested refinement, or a new ``xi_mode``."""
    from ..core.h5io import coordinate
    xi = grp_p["xi"]
    sel = slice(None)
    if res.xi is not None and np.asarray(res.xi).size != xi.shape[0]:
        rx, px = np.asarray(res.xi, float), xi[...]
        step = (rx.size - 1) // max(px.size - 1, 1)
        if step >= 1 and rx.size - 1 == step * (px.size - 1) and np.array_equal(rx[::step], px):
            sel = slice(None, None, step)      # a nested refinement: the pulse's own nodes
        else:
            xi = coordinate(g, "xi_mode", rx, units="m",
                            long_name="co-moving coordinate of the modes")
    return xi, sel


def _write_arrays(g, grp_p, res) -> None:
    """The eigenvalues on the ``eigenvalue`` coordinate and the mode fields on (eigenvalue, xi)."""
    from ..core.h5io import coordinate, describe
    nm = len(res.modes)
    eig = coordinate(g, "eigenvalue", np.arange(nm, dtype="i8"), units="1", dtype="i8",
                     long_name="eigenvalue index, by decreasing Re sigma")
    xi, sel = _mode_axis(g, grp_p, res)
    for part in ("real", "imag"):
        describe(g.create_dataset(f"sigma_{part}", data=getattr(res.sigmas, part)), "1/s",
                 f"eigenvalue sigma ({part} part), perturbations ~ exp(sigma t)", (eig,))
        describe(g.create_dataset(f"s_per_L_{part}",
                                  data=getattr(res.sigmas, part) / res.rate_unit), "1",
                 f"sigma L / c_p ({part} part): e-folds per pulse length travelled", (eig,))
    for name, (unit, long) in MODE_FIELDS.items():
        arr = (np.stack([m[name][sel] for m in res.modes]) if nm
               else np.zeros((0, xi.shape[0]), complex))
        for part in ("real", "imag"):
            describe(g.create_dataset(f"{name}_{part}", data=getattr(arr, part)), unit,
                     f"{long} ({part} part)", (eig, xi))


def write_spectrum(path, res, settings: dict, extra_attrs: dict | None = None):
    """Store `res` (a :class:`~slippulse.spectrum.pulse.PulseSpectrum`) as /pulses/<label>/spectrum (replacing an earlier one), atomically.

    Layout (xarray: ``open_datatree(path, engine="h5netcdf")``): coordinate ``eigenvalue`` (index,
    by decreasing Re σ); ``sigma_real``/``sigma_imag`` (1/s) and ``s_per_L_*`` on it; mode fields
    ``delta_*``, ``V_*``, ``phi_*``, ``lnv_*`` on (eigenvalue, xi), xi being the pulse's own
    coordinate in the parent group; scalars and the status as attributes (:func:`spectrum_attrs`,
    :func:`refine_attrs`, :func:`count_attrs`, the settings as ``setting_<key>``, then
    ``extra_attrs``, e.g. the settings' text and the attempt).
    """
    from ..core.h5io import atomic_update, upgrade_steady

    attrs = spectrum_attrs(res)
    if res.refined is not None:
        attrs.update(refine_attrs(res.refined))
    if res.count is not None:
        attrs.update(count_attrs(res.count))
    attrs.update({f"setting_{k}": v for k, v in settings.items()})
    attrs.update(extra_attrs or {})
    attrs.update({f"{k}_units": u for k, u in ATTR_UNITS.items() if k in attrs})

    def fill(h5):
        upgrade_steady(h5)                       # xi of every pulse group a dimension scale
        grp_p = h5["pulses"][res.label]
        if SPECTRUM_GROUP in grp_p:
            del grp_p[SPECTRUM_GROUP]
        g = grp_p.create_group(SPECTRUM_GROUP)
        for k, v in attrs.items():
            g.attrs[k] = v
        _write_arrays(g, grp_p, res)

    atomic_update(path, fill)


def read_spectrum(path, label):
    """The stored spectrum of a pulse as a dict (attrs + arrays), or None if there is none."""
    from ..core.h5io import labels_in, open_h5
    with open_h5(path) as h5:
        if label not in labels_in(h5, path):
            return None
        grp = h5["pulses"][label]
        if SPECTRUM_GROUP not in grp:
            return None
        g = grp[SPECTRUM_GROUP]
        out = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in g.attrs.items()}
        out["sigma"] = g["sigma_real"][...] + 1j * g["sigma_imag"][...]
        for name in MODE_FIELDS:
            out[name] = g[f"{name}_real"][...] + 1j * g[f"{name}_imag"][...]
        out["xi"] = (g["xi_mode"] if "xi_mode" in g else grp["xi"])[...]
        out["tau_d_ratio"] = float(grp.attrs["tau_d_ratio"])
        out["L"] = float(grp.attrs["L"])
        out["c_p"] = float(grp.attrs["c_p"])
    return out
