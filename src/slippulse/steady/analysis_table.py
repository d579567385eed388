"""Plain-text table of the analysis of a family (``slippulse steady analyse``, ``figures``)."""
from __future__ import annotations

from ..core.reference import paper_scaling


def format_table(rows):
    """Plain-text table of the per-pulse results (and the family fits if attached)."""
    cols = [("label", "{:>9s}"), ("beta", "{:9.5f}"), ("c_p", "{:10.2f}"), ("L", "{:10.4g}"),
            ("L_tilde", "{:9.4g}"), ("v_max", "{:10.3e}"), ("tau_max", "{:10.4e}"),
            ("tau_m_pulse", "{:11.5e}"), ("total_slip", "{:10.3e}"), ("G_bar_max", "{:9.3g}"),
            ("zeta", "{:7.3f}"), ("zeta_err", "{:8.3f}"), ("max_residual", "{:9.1e}")]
    heads = {"c_p": "c_p[m/s]", "L": "L[m]", "v_max": "v_max[m/s]", "tau_max": "tau_max[Pa]",
             "tau_m_pulse": "min_tau[Pa]", "total_slip": "slip[m]", "G_bar_max": "Gmax[J/m2]",
             "max_residual": "max|res|"}
    widths = [len(fmt.format("x" if "s}" in fmt else 0.0)) for _, fmt in cols]
    lines = [" ".join(f"{heads.get(c, c):>{w}s}" for (c, _), w in zip(cols, widths))]
    for r in rows:
        lines.append(" ".join(fmt.format(r[c]) for c, fmt in cols))
    if rows:
        lines.extend(_table_notes(rows))
    fam = rows[0].get("family") if rows else None
    if fam:
        if fam.get("skipped_unconverged"):
            lines.append("left out (marked converged=False): "
                         + ", ".join(fam["skipped_unconverged"]))
        lines.append(f"tau_m = {fam['tau_m']:.6e} Pa (min tau of the smallest tau_d)")
        if "scaling" in fam:
            s = fam["scaling"]
            ps = paper_scaling()
            lines.append(
                f"scaling fit on tau_d/tau_min in [{s['window'][0]}, {s['window'][1]}] ({s['n']} pulses): "
                f"tau*~ = {s['tau_star']:.5f} ± {s['tau_star_err']:.1g}, a_v = {s['a_v']:.4f} ± "
                f"{s['a_v_err']:.1g}, a_G = {s['a_G']:.4f} ± {s['a_G_err']:.1g} "
                f"(paper: {ps['tau_star']:g}, {ps['a_v']:g}, {ps['a_G']:g})")
            for eq, k in (("beta", "a_v"), ("L", "a_G")):
                d = fam.get(f"scaling_{eq}")
                if d:
                    lines.append(f"  Eq. {3 if eq == 'beta' else 4} alone: tau*~ = {d['tau_star']:.5f} ± "
                                 f"{d['tau_star_err']:.1g}, {k} = {d[k]:.4f} ± {d[k + '_err']:.1g}")
        else:
            lines.append(f"scaling fit: not done ({fam['scaling_error']})")
        if "fracture" in fam:
            f = fam["fracture"]
            lines.append(f"G_c = {f['G_c']:.3g} ± {f['G_c_err']:.2g} J/m^2 (paper ~0.6), "
                         f"delta_c = {f['delta_c']:.3g} m: the bend of the median G-bar(delta) "
                         f"curve of {f['n_curves']} pulses, local log-slope {f['slope']} "
                         f"(± : from slopes {f['band'][0]} to {f['band'][1]}, "
                         f"{f['G_c_lo']:.3g}-{f['G_c_hi']:.3g} J/m^2)")
        else:
            lines.append(f"G_c: not done ({fam['fracture_error']})")
    return "\n".join(lines)


def _table_notes(rows):
    """What the table's numbers are worth: the columns without an uncertainty, and why ζ or its
    error is NaN where it is (by reason, with the pulses it concerns)."""
    import math
    notes = ["no uncertainty in this table but zeta's: beta ... Gmax are measured on each pulse's "
             "own grid (`steady family` grid-checks its pulses at 2N - 1: |dbeta| <= 1e-5, "
             "|dL|/L <= 1e-4); max|res| is the solver's residual, not an error"]
    why = {}
    for r in rows:
        if not math.isfinite(r["zeta"]):
            reason = f"zeta not fitted: {r.get('zeta_note') or 'no reason recorded'}"
        elif not math.isfinite(r["zeta_err"]):
            reason = ("zeta_err not estimated: " + (r.get("zeta_note") or "no reason recorded"))
        else:
            continue
        why.setdefault(reason, []).append(r["label"])
    for reason, labels in why.items():
        shown = ", ".join(labels[:4]) + (f" ... ({len(labels)} pulses)" if len(labels) > 4 else "")
        notes.append(f"{reason} ({shown})")
    return notes
