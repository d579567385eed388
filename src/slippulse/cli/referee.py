"""``slippulse steady referee``: the referee's checks on stored pulses (docs/branches.md,
docs/results.md): Brantut, Garagash & Noda (2019)'s slip criterion against the growth rates of
record, the paper's Eqs. 3–4 refitted over its own range, and ζ, Ḡ_max at the smallest τ_d."""
from __future__ import annotations

import os

from ..core import h5io
from ..core.errors import UsageError

#: τ_d/τ_min windows of the Eqs. 3–4 refit: the paper's range and two narrower ones.
WINDOWS = ((1.015, 1.2), (1.015, 1.1), (1.015, 1.05))


def _rates(path):
    """τ_d/τ_min → (s L/c_p, err) of the rates of record of a records file
    (:func:`slippulse.spectrum.records.read_rates`)."""
    from ..spectrum.records import read_rates

    if not os.path.isfile(path):
        raise UsageError(f"--records={path!r} is invalid: no such file (a records TOML, e.g. "
                         "docs/results/records.toml)")
    try:
        r = read_rates(path)
    except ValueError as exc:
        raise UsageError(f"--records={path!r} is invalid: {exc}") from None
    return {q: (s, e) for q, s, e in zip(r["tau_d_ratio"], r["s"], r["s_err"])}


def cmd_referee(args) -> int:
    from ..steady.analysis import edge_record, paper_range_fit, slip_criterion

    rates = _rates(args.records) if args.records else {}
    rows, params = [], None
    for f in args.file:          # derivatives within each file (a family or a pair of pulses)
        pulses = []
        for lab in h5io.list_pulses(f):
            p, params = h5io.read_pulse(f, lab)
            if p.converged:
                pulses.append(p)
        rows += slip_criterion(pulses, params, rates)
    print("label tau_d/tau_min beta L(m) slip_b(m) db/dq(m) Brantut sL/c_p +- err sign agree")
    for r in rows:
        print(f"{r['label']} {r['tau_d_ratio']:.7f} {r['beta']:.6g} {r['L']:.5g} {r['slip']:.5e} "
              f"{r['db_dq']:.4e} {r['predicted']} {r['s']:.5g} {r['s_err']:.2g} {r['s_sign']} "
              f"{r['agree']}")
    cmp = [r for r in rows if r["agree"] is not None]
    with_d = [r for r in rows if r["db_dq"] == r["db_dq"]]
    neg = sum(r["db_dq"] < 0 for r in with_d)
    fits_line = []
    for window in WINDOWS:
        try:
            fit = paper_range_fit(args.file[0], window)
        except ValueError as exc:
            print(f"window {window}: no fit ({exc})")
            continue
        print(f"window {window}: the paper's constants {fit['paper']}: rms log residual "
              f"{fit['paper_rms']:.3e}")
        for eq in ("both", "beta", "L"):
            f = fit[eq]
            print(f"  fit {eq} (n={f['n']}): tau_star={f['tau_star']:.6f} +- "
                  f"{f['tau_star_err']:.1e} a_v={f['a_v']:.4f} +- {f['a_v_err']:.1e} "
                  f"a_G={f['a_G']:.4f} +- {f['a_G_err']:.1e} rms={f['rms']:.3e}")
        if window == WINDOWS[0]:
            f = fit["both"]
            fits_line.append(f"Eqs. 3-4 on {window}: tau_star = {f['tau_star']:.5f} ± "
                             f"{f['tau_star_err']:.1e} (1 sigma, fit only)")
    e = edge_record(args.file[0])
    print(f"edge record {e['label']}: zeta={e['zeta']:.4f} +- {e['zeta_err']:.4f} "
          f"(at bound: {e['zeta_at_bound']}) G_bar_max={e['G_bar_max']:.5g} J/m^2 "
          f"tau_m_used/tau_min={e['tau_m_used'] / params.tau_min:.6f}")
    print(f"referee {' '.join(args.file)}: db/dq < 0 at {neg} of {len(with_d)} pulses with a "
          f"derivative (second-order differences; no error estimate); compared with a resolved "
          f"rate at {len(cmp)}: agree at {sum(r['agree'] for r in cmp)}; "
          + "; ".join(fits_line + [f"zeta = {e['zeta']:.4f} ± {e['zeta_err']:.4f} at "
                                   f"{e['label']}"]))
    return 0


def register(ss) -> None:
    p = ss.add_parser("referee", help="the referee's checks: slip criterion, Eqs. 3-4 over the "
                                      "paper's range, edge record",
                      description="Brantut, Garagash & Noda (2019)'s criterion (a pulse is "
                                  "unstable where its total slip falls with the load, db/dtau_d "
                                  "< 0) at every converged pulse of each FILE, compared with the "
                                  "growth rates of --records; the paper's Eqs. 3-4 refitted over "
                                  "tau_d/tau_min in [1.015, 1.2], [1.015, 1.1], [1.015, 1.05] on "
                                  "the first FILE, with the paper's constants' residual; zeta and "
                                  "G-bar max at its smallest tau_d (docs/branches.md).")
    p.add_argument("file", metavar="FILE", nargs="+",
                   help="family files (derivatives within each; the first: fits and edge record)")
    p.add_argument("--records", default=None, metavar="TOML",
                   help="records file whose [spectrum.\"LABEL\"] s_per_L the criterion is "
                        "compared with (e.g. docs/results/records.toml; default: no comparison)")
    p.set_defaults(func=cmd_referee)
