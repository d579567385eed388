"""The branches of steady pulses in (τ_d/τ_min, L), each pulse coloured by its number of unstable
eigenvalues (docs/branches.md §4).

A pulse's number is the argument-principle count stored with its spectrum (``steady stability
--count``: the eigenvalues in the counted box, exact for the discrete operator) where there is one
(filled marker), else the number of eigenvalues with Re σ > 0 that the eigen-search found (hollow
marker: a lower bound, the search is not exhaustive); a pulse with no spectrum is only a point of
its branch's line. A branch is one file (or several taken together); its pulses are joined in
the order they were traced (``trace_position``, the step signed by the direction, from ``steady
branch-trace``: traces up and down from one pulse merge into one order) or, without it or where
traces from different pulses repeat a position, by decreasing τ_d. A count whose box lies right of
an unstable eigenvalue the search found adds it, and is then drawn as found, not counted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from .metadata import params_metadata
from ..core.atomic import save_figure

#: Marker colours by number of unstable eigenvalues (3 stands for 3 or more).
COUNT_COLORS = {0: "#1b9e77", 1: "#d95f02", 2: "#7570b3", 3: "#e7298a"}
LINE_COLORS = ("0.25", "#1f78b4", "#33a02c", "#a6761d", "#666666")


@dataclass
class BranchSeries:
    """One branch: its pulses in branch order. ``count`` is the argument-principle count (nan:
    none), ``found`` the eigenvalues with Re σ > 0 the search found (−1: no spectrum), ``below``
    those of them left of the counted box (0 < Re σ < its left edge; None: none anywhere)."""
    name: str
    q: np.ndarray
    L: np.ndarray
    count: np.ndarray
    found: np.ndarray
    below: np.ndarray | None = None

    def unstable(self):
        """(number, counted) per pulse: the count plus the eigenvalues found left of its box
        where there is a count, else the number found; −1 where the pulse has no spectrum.
        Counted (exact) only where nothing was found left of the box: the box does not see a
        mode there (near τ_min the leading one), so a count alone would say 0 where it is 1."""
        below = np.zeros(self.q.size, int) if self.below is None else np.asarray(self.below)
        has = np.isfinite(self.count)
        n = np.where(has, np.nan_to_num(self.count, nan=-1) + below, self.found).astype(int)
        return n, has & (below == 0)


def length_ratio(branch: BranchSeries, reference: BranchSeries):
    """L of ``branch`` over L of ``reference`` at the same τ_d, at each pulse of ``branch`` inside
    the reference's τ_d range (the reference's ln L interpolated linearly in τ_d; the reference
    must be single-valued in τ_d, as the main family is); nan outside it."""
    d = np.diff(reference.q)
    if not (np.all(d > 0) or np.all(d < 0)):       # turns in τ_d along the branch: a fold
        raise ValueError(f"{reference.name}: tau_d not monotone along it; no ratio at equal tau_d")
    o = np.argsort(reference.q)
    qr, lr = reference.q[o], np.log(reference.L[o])
    inside = (branch.q >= qr[0]) & (branch.q <= qr[-1])
    out = np.full(branch.q.size, np.nan)
    out[inside] = branch.L[inside] / np.exp(np.interp(branch.q[inside], qr, lr))
    return out


def branch_series(paths, name=None) -> BranchSeries:
    """The converged pulses of one file, or of several files taken as one branch (e.g. a family
    and its continuation above 1.2 τ_min), as a :class:`BranchSeries` (τ_d, L, stored counts)."""
    import os
    from ..core.h5io import labels_in, open_h5, pulse_converged
    paths = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    rows = {}
    for path in paths:
        with open_h5(path, "FILE") as h5:
            for lab in labels_in(h5, path):
                grp = h5["pulses"][lab]
                if not pulse_converged(grp, path):
                    continue
                a = grp.attrs
                count, found, below = math.nan, -1, 0
                if "spectrum" in grp and grp["spectrum"].attrs.get("status") == "converged":
                    sp = grp["spectrum"]
                    sa = sp.attrs
                    found = int(sa.get("n_unstable", 0))
                    if "count" in sa:
                        count = float(sa["count"])
                        below = _found_left_of_box(sp)
                step = a.get("trace_position")
                q = float(a["tau_d_ratio"])
                key = (round(q, 9), None if step is None else int(step))
                if key not in rows or (math.isnan(rows[key][2]) and not math.isnan(count)):
                    rows[key] = (q, float(a["L"]), count, found, key[1], below)   # in two files: once
    rows = list(rows.values())
    if not rows:
        raise ValueError(f"{', '.join(map(str, paths))}: no converged pulse")
    steps = [r[4] for r in rows]
    if None not in steps and len(set(steps)) == len(steps):   # one trace (or up and down from one pulse)
        rows.sort(key=lambda r: r[4])
    else:
        rows.sort(key=lambda r: -r[0])
    q, L, c, f, _, below = (np.array(col) for col in zip(*rows))
    return BranchSeries(name or os.path.splitext(os.path.basename(paths[0]))[0], q.astype(float),
                        L.astype(float), c.astype(float), f.astype(int), below.astype(int))


def _found_left_of_box(sp) -> int:
    """The eigenvalues of a stored spectrum (``s_per_L_real``, c_p/L) above the search's floor
    (Re σ > ``setting_min_re_c_over_L``) left of its counted box (``count_box_c_over_L``[0]);
    0 where either is missing."""
    box = sp.attrs.get("count_box_c_over_L")
    if box is None or "s_per_L_real" not in sp:
        return 0
    re = np.asarray(sp["s_per_L_real"][...], float)
    floor = float(sp.attrs.get("setting_min_re_c_over_L", 0.0))     # the search's "unstable"
    return int(np.count_nonzero((re > floor) & (re < float(np.ravel(box)[0]))))


def plot_branch_map(series, path, params=None, title=None, dpi=150, zoom=None) -> str:
    """L against τ_d/τ_min for each :class:`BranchSeries` (a line per branch, log L), each pulse
    with a spectrum marked in the colour of its number of unstable eigenvalues: filled where
    counted by the argument principle, hollow where only found by the eigen-search.
    ``zoom`` = (q0, q1): a second panel with that τ_d range, L scaled to the pulses in it (where
    branches crowd, e.g. about a fold near τ_min)."""
    if zoom is not None and not (zoom[0] < zoom[1]):
        raise ValueError(f"zoom={zoom!r}: need q0 < q1")
    fig = Figure(figsize=(11.0, 5.0) if zoom else (7.5, 5.0))
    if zoom:
        ax, az = fig.subplots(1, 2, gridspec_kw={"width_ratios": (3, 2)})
    else:
        ax, az = fig.subplots(), None
    shown = _draw_branches(ax, series)
    if az is not None:
        _draw_branches(az, series)
        inside = np.concatenate([b.L[(b.q >= zoom[0]) & (b.q <= zoom[1])] for b in series])
        az.set_xlim(*zoom)
        az.set_yscale("linear")             # a narrow range: plain metres read better
        if inside.size:
            az.set_ylim(inside.min() / 1.1, inside.max() * 1.1)
        az.set_title(f"τ_d / τ_min in [{zoom[0]:g}, {zoom[1]:g}]", fontsize=9)
        ax.axvspan(*zoom, color="0.85", alpha=0.5, zorder=0)
    handles = ax.get_legend_handles_labels()[0]
    for k, counted in sorted(shown, key=lambda t: (not t[1], t[0])):
        col = COUNT_COLORS[k]
        word = f"{k}{'+' if k == 3 else ''} unstable"
        handles.append(Line2D([], [], ls="", marker="o", mec=col, mfc=col if counted else "white",
                              mew=1.5, label=f"{word} ({'counted' if counted else 'found, not counted'})"))
    ax.legend(handles=handles, fontsize=7.5, loc="best")
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=dpi, metadata=params_metadata(params, path) if params else None)
    return path


def _draw_branches(ax, series) -> set:
    """The branches' lines and markers on ``ax`` (log L); returns the (number, counted) kinds
    drawn, for the legend."""
    shown = set()
    for i, b in enumerate(series):
        ax.plot(b.q, b.L, "-", color=LINE_COLORS[i % len(LINE_COLORS)], lw=1.0, zorder=1,
                label=b.name)
        n, counted = b.unstable()
        for k in range(b.q.size):
            if n[k] < 0:
                continue
            col = COUNT_COLORS[min(int(n[k]), 3)]
            shown.add((min(int(n[k]), 3), bool(counted[k])))
            ax.plot(b.q[k], b.L[k], "o", ms=6, zorder=2, mec=col,
                    mfc=col if counted[k] else "white", mew=1.5)
    ax.set_yscale("log")
    ax.set_xlabel("τ_d / τ_min")
    ax.set_ylabel("pulse length L (m, full width at half maximum of ln(v/v* + 1))")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    return shown
