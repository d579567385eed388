"""steady/existence_map.py and param_continuation.py: the classification of (b, α) points and
continuation in the parameters (issue 21 item 4)."""
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
    docs/parameters.md §3) along the geometric path: found, one hump, β of the map (0.0286)."""
    import dataclasses as dc

    from slippulse.steady.param_continuation import continue_in_params, judge
    target = dc.replace(DEFAULT, b=0.1)
    sol, path = continue_in_params(DEFAULT, target, 1.2, n_points=500)
    assert path[-1][:2] == (1.0, True) and sol.problem.params == target
    assert judge(sol) == (True, "")
    assert abs(sol.beta - 0.0286) < 5e-4
