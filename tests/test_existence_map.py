"""The existence map (slippulse.steady.existence_map) and param_continuation: the
classification of (b, α) points and continuation in the parameters."""
import numpy as np
import pytest

from slippulse.core.params import DEFAULT
from slippulse.steady.existence_map import (ABOVE_PEAK, FAILED, FOUND, NO_N_SHAPE, classify_shape,
                                            existence_map, write_map)


def test_shape_classes():
    st, ratio, why, _ = classify_shape(DEFAULT, 0.075, 0.005, 1.2)
    assert st == FOUND and abs(ratio - DEFAULT.tau_peak / DEFAULT.tau_min) < 1e-12
    st, _, why, p = classify_shape(DEFAULT, 0.01, 0.005, 1.2)           # f0 b < α
    assert st == NO_N_SHAPE and "must exceed alpha" in why and p is None
    st, _, why, _ = classify_shape(DEFAULT, 0.075, 1e-9, 1.2)           # no minimum below c_s
    assert st == NO_N_SHAPE and "without a minimum" in why
    st, ratio, why, _ = classify_shape(DEFAULT, 0.075, 0.015, 1.2)      # shallow N
    assert st == ABOVE_PEAK and ratio < 1.2 and "no stick state" in why


def test_map_without_solves_and_file(tmp_path):
    m = existence_map([0.01, 0.075], [0.015, 1e-9], n_points=500)
    assert m.solves == 0
    assert m.guess_status.tolist() == [[NO_N_SHAPE, NO_N_SHAPE], [ABOVE_PEAK, NO_N_SHAPE]]
    assert np.all(np.isnan(m.beta))
    path = str(tmp_path / "m.h5")
    write_map(path, m)
    import h5py
    with h5py.File(path) as h5:
        assert h5["guess_status"].shape == (2, 2) and h5["parameters"].attrs["mu"] == DEFAULT.mu


def test_map_table_point_found_both_ways():
    """Table I at 1.2 τ_min, N = 500: found from the guess and by continuation (the start), with
    the β of a direct solve."""
    m = existence_map([0.075], [0.005], n_points=500)
    assert m.guess_status[0, 0] == FOUND and m.cont_status[0, 0] == FOUND
    assert abs(m.beta[0, 0] - 0.00724166628630679) < 1e-9 and m.agree[0, 0] == 0.0


@pytest.mark.slow
def test_continuation_in_params_reaches_b_0_1():
    """From Table I's pulse to b = 0.1 (where the built-in guess at N = 500 does not converge,
    docs/guide.md, Other parameters) along the geometric path: found, one hump, β of the map (0.0286)."""
    import dataclasses as dc

    from slippulse.steady.param_continuation import continue_in_params, judge
    target = dc.replace(DEFAULT, b=0.1)
    sol, path = continue_in_params(DEFAULT, target, 1.2, n_points=500)
    assert path[-1][:2] == (1.0, True) and sol.problem.params == target
    assert judge(sol) == (True, "")
    assert abs(sol.beta - 0.0286) < 5e-4


def test_map_on_a_dask_cluster_is_the_serial_map_and_resumes(tmp_path):
    """Two points at N = 500: the map computed on a dask.distributed LocalCluster of two worker
    threads (cheap to start; the same submit/as_completed path as processes or a scheduler) is
    the serial one. Each solve is kept in the checkpoint as it arrives; a rerun reads them back
    instead of solving (a value altered in the file comes back altered)."""
    import json

    from slippulse.core.executor import ExecutorSettings
    b, a = [0.075], [0.005, 0.0075]
    serial = existence_map(b, a, n_points=500)
    ck = str(tmp_path / "map.partial.json")
    par = existence_map(b, a, n_points=500, checkpoint=ck,
                        executor=ExecutorSettings(workers=2, processes=False))
    for name in ("guess_status", "cont_status", "shape_status"):
        assert np.array_equal(getattr(par, name), getattr(serial, name)), name
    assert np.allclose(par.beta, serial.beta, rtol=1e-12, equal_nan=True)
    assert par.guess_reason.tolist() == serial.guess_reason.tolist()
    assert par.cont_reason.tolist() == serial.cont_reason.tolist()
    assert par.solves == serial.solves and FOUND in par.cont_status
    with open(ck) as fh:
        d = json.load(fh)
    assert set(d["solves"]) >= {"guess 0 0", "guess 0 1", "start"}
    assert serial.guess_status[0, 0] == FOUND          # Table I: β from the guess solve
    d["solves"]["guess 0 0"]["measures"][0] = 0.5
    with open(ck, "w") as fh:
        json.dump(d, fh)
    again = existence_map(b, a, n_points=500, checkpoint=ck)
    assert again.beta[0, 0] == 0.5
    assert np.allclose(again.beta[0, 1:], serial.beta[0, 1:], rtol=1e-12, equal_nan=True)


def test_cli_refuses_bad_input_in_one_line(tmp_path):
    """`slippulse steady existence-map`: bad values name the option and its range (exit 2), and
    nothing is written."""
    import os
    import sys
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import cli_inproc
    out = tmp_path / "m.h5"
    for args, msg in ((["--workers", "0"], "--workers=0 is invalid"),
                      (["--b", "-0.1"], "--b=[-0.1] is invalid"),
                      (["--tau-d", "0.9"], "--tau-d=0.9 is invalid"),
                      (["--points", "20"], "--points=20 is invalid")):
        r = cli_inproc.run(["steady", "existence-map", "--out", out, *args])
        assert r.returncode == 2 and msg in r.stderr, (args, r.stderr)
        assert r.stderr.strip().count("\n") == 0 and not out.exists()
