"""The referee's checks on stored pulses (docs/branches.md): Brantut, Garagash & Noda (2019)'s
slip criterion against the growth rates of record, Eqs. 3-4 refitted over the paper's range, and
ζ, Ḡ_max at the smallest τ_d of a family.

    python steady/referee_checks.py FAMILY.h5 [MORE.h5 ...] [--records docs/results/records.toml]
"""
import argparse
import tomllib

from slippulse.core import h5io
from slippulse.steady.analysis import edge_record, paper_range_fit, slip_criterion


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", help="family files (the first: fit window and edge record)")
    ap.add_argument("--records", default="docs/results/records.toml")
    a = ap.parse_args()
    with open(a.records, "rb") as fh:
        rec = tomllib.load(fh)
    rates = {h5io.label_ratio(k): (v["s_per_L"]["value"], v["s_per_L"]["err"])
             for k, v in rec.get("spectrum", {}).items()}
    rows, params = [], None
    for f in a.files:            # derivatives within each file (a family or a pair of pulses)
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
    neg = sum(r["db_dq"] < 0 for r in rows if r["db_dq"] == r["db_dq"])
    print(f"db/dq < 0 at {neg} of {sum(r['db_dq'] == r['db_dq'] for r in rows)} pulses with a "
          f"derivative; compared with a resolved s at {len(cmp)}: agree at "
          f"{sum(r['agree'] for r in cmp)}")
    for window in ((1.015, 1.2), (1.015, 1.1), (1.015, 1.05)):
        fit = paper_range_fit(a.files[0], window)
        pp = fit["paper"]
        print(f"window {window}: the paper's constants {pp}: rms log residual "
              f"{fit['paper_rms']:.3e}")
        for eq in ("both", "beta", "L"):
            f = fit[eq]
            print(f"  fit {eq} (n={f['n']}): tau_star={f['tau_star']:.6f} +- "
                  f"{f['tau_star_err']:.1e} a_v={f['a_v']:.4f} +- {f['a_v_err']:.1e} "
                  f"a_G={f['a_G']:.4f} +- {f['a_G_err']:.1e} rms={f['rms']:.3e}")
    e = edge_record(a.files[0])
    print(f"edge record {e['label']}: zeta={e['zeta']:.4f} +- {e['zeta_err']:.4f} "
          f"(at bound: {e['zeta_at_bound']}) G_bar_max={e['G_bar_max']:.5g} J/m^2 "
          f"tau_m_used/tau_min={e['tau_m_used'] / params.tau_min:.6f}")


if __name__ == "__main__":
    main()
