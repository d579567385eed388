"""The rows of a scan's finished cases and the variant of a ±ε pair against the base pair
(timedomain.perturbation.scan_rows, pair_variant): what the instability report reads."""
import h5py

from slippulse.timedomain.perturbation import pair_variant, read_row, scan_rows
from slippulse.timedomain.scan import parse_scan

_KEYS = ("fate", "status", "s_per_L", "s_per_L_err", "s_per_s", "s_per_s_err", "fit_x0",
         "fit_x1", "fit_n", "fit_sign", "s_per_L_from_L", "mode_spread", "travelled", "t_end",
         "L_end", "v_max_end", "n_steps", "n_points", "wall_time", "tau_d_ratio", "L0", "c_p0",
         "beta0", "v_max0")


def test_scan_rows_reads_the_finished_cases_in_order_and_skips_the_others(tmp_path):
    scan = parse_scan({"scan": {"name": "x", "out_dir": str(tmp_path / "x")},
                       "defaults": {"label": "td1.2000"}, "grid": {"eps": [1e-3, -1e-3, 1e-2]}})
    (tmp_path / "x").mkdir()
    done = [scan.cases[0], scan.cases[2]]
    for k, c in enumerate(scan.cases):
        with h5py.File(scan.out_file(c), "w") as h5:
            h5.attrs.update({key: float(k) for key in _KEYS if key not in ("fate", "status")})
            h5.attrs.update({"fate": "arrested", "status": "arrested", "case_json": c.case_json,
                             "complete": c in done})
    rows = scan_rows(scan)
    assert [r["id"] for r in rows] == [c.id for c in done]
    assert [r["eps"] for r in rows] == [1e-3, 1e-2]
    assert rows[1]["s_per_L"] == 2.0 and rows[1]["label"] == "td1.2000"
    assert rows[0]["file"] == read_row(scan.out_file(done[0]))["file"]


def test_pair_variant_names_every_setting_that_differs():
    base = {"eps": 1e-3, "dx": 4e-3, "xi_stab": 1.0, "ahead": 2.0, "behind": 3.0,
            "history": "steady", "perturbation": "mode"}
    assert pair_variant(dict(base), base) == "base"
    assert pair_variant(dict(base, eps=1e-2), base) == "ε = 0.01"
    assert pair_variant(dict(base, dx=2e-3), base) == "Δx = 2 mm, ξ_s = 1"
    assert pair_variant(dict(base, ahead=4.0, history="none"), base) == \
        "domain 3+4 L; history none"
    assert pair_variant(dict(base, perturbation="mode_front"), base) == \
        "perturbation mode_front"
