"""The edges of the pulses of a deep family against L (docs/results.md, "The edges become fixed
structures"): each pulse's :func:`.measures.edge_structure`, Ḡ at fixed slip, and the distance of
its two edge profiles from those of the longest pulse.

The leading edge is compared in Lorentz-contracted units (ξ/√(1−β²), v√(1−β²)) over ±30 mm
(contracted) about its steepest point; the healing front over ±5 m about its own.
"""
from __future__ import annotations

import math

import numpy as np

from .measures import breakdown_energy, edge_structure, profile_distance

#: Slips (m) at which Ḡ(δ) is quoted.
G_SLIPS = (2e-6, 5e-6, 20e-6)
#: Pulses with τ_d/τ_min below this enter; one per this factor in L.
Q_MAX = 1.06
L_STEP = 1.1
#: Half-widths of the profile comparison: leading edge (m, contracted), healing front (m).
FRONT_HALF_WIDTH = 0.03
BACK_HALF_WIDTH = 5.0


def edge_study(pulses, params):
    """Edge measures of ``pulses`` (h5io.Pulse, with profiles) against L.

    Returns a list of (pulse, dict) sorted by L: the keys of :func:`edge_structure`, ``G`` (Ḡ at
    :data:`G_SLIPS`, J/m², τ_m the least τ over the pulses), ``G_max``, ``front_dist`` and
    ``back_dist`` (max |Δ ln v| against the longest pulse). One pulse per factor
    :data:`L_STEP` in L, with τ_d/τ_min < :data:`Q_MAX`.
    """
    if not pulses:
        raise ValueError("no pulse with profiles for the edge study")
    tau_m = min(float(p.tau.min()) for p in pulses)
    rows = []
    for p in sorted(pulses, key=lambda p: p.L):
        if p.tau_d_ratio >= Q_MAX or (rows and p.L < L_STEP * rows[-1][1]["L"]):
            continue
        e = edge_structure(p.xi, p.v, p.tau, params.v_star, p.v_stick)
        delta, G = breakdown_energy(p.xi, p.v, p.tau, p.v_stick, p.beta, params.c_s, tau_m)
        o = np.argsort(delta)
        e["G"] = [float(np.interp(dd, delta[o], G[o])) for dd in G_SLIPS]
        e["G_max"] = float(G.max())
        rows.append((p, e))
    if not rows:
        raise ValueError(f"no pulse with tau_d/tau_min < {Q_MAX} for the edge study")
    ref_p, ref_e = rows[-1]
    gr = math.sqrt(1 - ref_p.beta ** 2)
    for p, e in rows:
        g = math.sqrt(1 - p.beta ** 2)
        e["front_dist"] = profile_distance(p.xi / g, np.log(p.v * g), e["x_front"] / g,
                                           ref_p.xi / gr, np.log(ref_p.v * gr),
                                           ref_e["x_front"] / gr, FRONT_HALF_WIDTH)
        e["back_dist"] = profile_distance(p.xi, np.log(p.v), e["x_back"], ref_p.xi,
                                          np.log(ref_p.v), ref_e["x_back"], BACK_HALF_WIDTH)
    return rows
