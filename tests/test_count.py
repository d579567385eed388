"""The argument-principle count of eigenvalues (slippulse.spectrum.count) and the refinement's
error estimate (slippulse.spectrum.refine), on operators whose answers are known."""
import math

import numpy as np
import pytest

from slippulse.core.executor import ExecutorSettings
from slippulse.spectrum.count import arg_det, count_unstable, zeros_in_box
from slippulse.spectrum.refine import RefinedRate


class _Diag:
    """M(σ) = Q diag(σ − λ_j) Q⁻¹ with known zeros λ_j (a dense, non-normal-looking matrix)."""

    rate_unit = 1.0

    def __init__(self, lams, n=12, seed=0):
        rng = np.random.default_rng(seed)
        self.lams = np.concatenate([lams, 50.0 + rng.uniform(1, 5, n - len(lams))])
        self.Q = rng.normal(size=(n, n)) + 1j * rng.normal(size=(n, n))
        self.Qi = np.linalg.inv(self.Q)

    def matrices(self, z, deriv=False):
        dM = np.eye(self.lams.size, dtype=complex) if deriv else None
        return self.Q @ np.diag(z - self.lams) @ self.Qi, dM


def test_arg_det_matches_numpy():
    rng = np.random.default_rng(3)
    M = rng.normal(size=(9, 9)) + 1j * rng.normal(size=(9, 9))
    _, a = arg_det(M)
    assert abs(math.remainder(a - np.angle(np.linalg.det(M)), 2 * math.pi)) < 1e-12


@pytest.mark.parametrize("lams, expected", [
    ([0.5, 2 + 1j, 2 - 1j, 5.0, -1.0, 0.3 + 6j], 3),     # 5 (right), -1 (left), 6i (above) outside
    ([-0.2, 4.5], 0),
    ([0.02 + 0.1j, 0.02 - 0.1j, 3.9], 3),                  # close to the left and right edges
])
def test_count_finds_the_zeros_inside_the_box(lams, expected):
    res = count_unstable(_Diag(np.array(lams, complex)), (0.01, 4.0, 4.0))
    assert res.status == "converged", res.message
    assert res.count == expected
    assert abs(res.winding - expected) < 0.05


@pytest.mark.parametrize("lams, expected", [
    ([0.0102 + 1.0j, 0.0102 + 1.0001j], 2),              # a pair 2e-4 inside the left edge
    ([0.0105 + 1.3j, 0.0105 + 1.30002j, 0.0103 - 2.1j, 0.0103 - 2.10001j], 4),
])
def test_count_sees_zeros_closer_to_the_contour_than_the_spacing(lams, expected):
    """Zeros just inside the edge turn the phase by about pi each within their own distance; the
    wrapped steps alone miss whole turns (1 and 2 here), the first-order reach does not."""
    op = _Diag(np.array(lams, complex))
    res = count_unstable(op, (0.01, 4.0, 4.0))
    assert res.status == "converged", res.message
    assert res.count == expected and res.reach <= 0.6
    blind = count_unstable(op, (0.01, 4.0, 4.0), derivative=False)
    assert blind.count != expected and math.isnan(blind.reach)   # what the check is for


class _Continuum:
    """diag(σ − λ_j): a discrete 'continuum' of zeros 0.006 left of the left edge (Im spacing
    0.1, like the grid's continuum near the imaginary axis) and one zero inside at 0.5."""

    rate_unit = 1.0

    def __init__(self):
        self.lams = np.concatenate([-0.001 + 1j * np.arange(-6.0, 6.0 + 1e-9, 0.1), [0.5]])

    def matrices(self, z, deriv=False):
        dM = np.eye(self.lams.size, dtype=complex) if deriv else None
        return np.diag(z - self.lams), dM


@pytest.mark.slow
def test_count_is_not_fooled_by_a_continuum_just_outside_the_edge():
    """Each zero outside turns the phase by about -pi as the left edge passes it; the phase-only
    walk aliases that drift (it counts -7 here), the derivative-checked walk counts the one."""
    res = count_unstable(_Continuum(), (0.005, 4.0, 4.0), max_evals=2000)
    assert res.status == "converged", res.message
    assert res.count == 1
    blind = count_unstable(_Continuum(), (0.005, 4.0, 4.0), max_evals=2000, derivative=False)
    assert blind.count != 1


class _Drift(_Diag):
    """_Diag times e^{Tσ} per row: det M gains e^{nTσ}, a smooth phase drift of nT rad per unit
    of Im σ along the contour, as the N far zeros give the pulse operators at depth."""

    def __init__(self, lams, T, **k):
        super().__init__(lams, **k)
        self.T = T

    def matrices(self, z, deriv=False):
        M, _ = super().matrices(z, False)
        e = np.exp(self.T * z)
        dM = (np.eye(self.lams.size) + self.T * M) * e if deriv else None
        return M * e, dM


@pytest.mark.parametrize("lams, expected", [
    ([0.5, 2 + 1j, 2 - 1j, -1.0], 3),
    ([0.0102 + 1.0j, 0.0102 + 1.0001j, 3.9], 3),          # a close pair under the drift
])
def test_count_follows_a_large_smooth_phase_drift_with_few_points(lams, expected):
    """|g| ≈ 60 everywhere: the wrapped rule needs a point per 0.01 of contour, the trapezoid rule
    counts the same zeros with a fraction of the evaluations."""
    op = _Drift(np.array(lams, complex), T=5.0)            # n T = 60
    new = count_unstable(op, (0.01, 4.0, 4.0), max_evals=6000)
    old = count_unstable(op, (0.01, 4.0, 4.0), max_evals=6000, phase_rule="wrapped")
    assert new.status == old.status == "converged", (new.message, old.message)
    assert new.count == old.count == expected
    assert new.reach <= 0.6 and old.max_step <= 0.6
    assert new.n_evals < old.n_evals / 4


@pytest.mark.parametrize("lams", [[0.5, 2 + 1j, 2 - 1j, -1.0], [0.7, 3.0, 1 + 2j, 1 - 2j, 60.0]])
def test_the_counts_own_evaluations_locate_its_zeros(lams):
    """The moments of the walk (``zeros_in_box``), under the large smooth drift of g, put each
    counted zero within 4 % of the box of the true one, with no evaluation added; with one zero
    given (``known``) the others within 0.2 %."""
    op = _Drift(np.array(lams, complex), T=5.0)
    res = count_unstable(op, (0.01, 4.0, 4.0), max_evals=6000)
    inside = [z for z in lams if 0.01 <= z.real <= 4.0 and abs(z.imag) <= 4.0]
    est = zeros_in_box(res)
    assert res.count == len(inside) == est.size
    assert all(np.min(np.abs(est - z)) < 0.16 for z in inside)
    rest = zeros_in_box(res, known=[inside[0]])
    assert rest.size == len(inside) - 1
    assert all(np.min(np.abs(rest - z)) < 0.008 for z in inside[1:])
    assert zeros_in_box(res, known=inside).size == 0


def test_arg_det_derivative_is_jacobi_formula():
    from slippulse.spectrum.count import log_det_derivative
    rng = np.random.default_rng(5)
    A, B = (rng.normal(size=(7, 7)) + 1j * rng.normal(size=(7, 7)) for _ in range(2))
    z, h = 0.3 + 0.2j, 1e-6
    a, g = log_det_derivative(A + z * B, B)
    fd = (np.log(np.linalg.det(A + (z + h) * B)) - np.log(np.linalg.det(A + (z - h) * B))) / (2 * h)
    assert abs(g - fd) < 1e-6 * abs(g)
    assert abs(math.remainder(a - np.angle(np.linalg.det(A + z * B)), 2 * math.pi)) < 1e-12


def test_count_fails_honestly_when_the_budget_is_too_small():
    res = count_unstable(_Diag(np.array([0.02 + 0.1j, 0.02 - 0.1j], complex)), (0.01, 4.0, 4.0),
                         max_evals=26)
    assert res.status == "failed" and res.count is None
    assert "budget" in res.message


def test_count_box_must_lie_in_the_analytic_half_plane():
    with pytest.raises(ValueError, match="0 < x0 < x1"):
        count_unstable(_Diag(np.array([1.0], complex)), (0.0, 4.0, 4.0))


def test_refined_rate_sign_rule():
    r = RefinedRate(s=3.0, s_err=1.0, rate_unit=10.0)
    assert r.sign_resolved and r.describe().startswith("s L/c_p = 0.3")
    r = RefinedRate(s=3.0, s_err=2.0, rate_unit=10.0)
    assert not r.sign_resolved
    text = r.describe()
    assert text.startswith("sign not resolved") and "0.3 " not in text
    r = RefinedRate(s=-5.0, s_err=1.0, rate_unit=10.0)
    assert r.sign_resolved and r.per_length() == (-0.5, 0.1)


def test_count_of_the_1p2_pulse_in_the_product(tmp_path, pulse12, params):
    """`run_spectrum(count_box=...)` on the 1.2 τ_min pulse (N_0 = 300): one eigenvalue in
    [0.5, 34] × ±34 c_p/L (the search's one real mode, s L/c_p ≈ 22.65), the walk's criteria
    met and stored."""
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum.pulse import read_spectrum
    from slippulse.spectrum.family import SpectrumSettings, run_spectrum
    f = str(tmp_path / "one.h5")
    write_pulse(f, pulse12.to_pulse(), params)
    rep = run_spectrum(f, SpectrumSettings(extra=False, levels=0, level0_points=300, count_box=(0.5, 4.0, 4.0)))
    assert rep.failed == []
    st = read_spectrum(f, "td1.2000")
    assert st["count_status"] == "converged", st["count_message"]
    assert list(st["count_box_c_over_L"]) == pytest.approx([0.5, 1.5 * st["leading_s_per_L"],
                                                           1.5 * st["leading_s_per_L"]])
    assert st["count"] == 1 and abs(st["count_winding"] - 1.0) < 0.05
    assert st["count_max_reach_rad"] <= 0.6      # the trapezoid rule's criteria, all pairs


def test_cli_count_budget_bad_input_and_documented_default(tmp_path, pulse12, params):
    import re
    import cli_inproc
    import subprocess
    import sys
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum.family import COUNT_EVALS
    f = str(tmp_path / "one.h5")
    write_pulse(f, pulse12.to_pulse(), params)
    r = cli_inproc.run(["steady", "stability", f, "--count", "0.5", "4", "4", "--count-evals", "5"])
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "count_evals=5" in r.stderr
    r = cli_inproc.run(["steady", "stability", f, "--count", "0.5", "4", "4", "--workers", "0"])
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "--workers=0 is invalid" in r.stderr
    r = cli_inproc.run(["steady", "stability", f, "--count", "0.5", "4", "4", "--threads", "-2"])
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "--threads=-2 is invalid" in r.stderr
    h = subprocess.run([sys.executable, "-m", "slippulse", "steady", "stability", "--help"],
                       capture_output=True, text=True).stdout
    m = re.search(r"--count-evals N\s+budget of det M evaluations per count \(default (\d+)", h)
    assert m and int(m.group(1)) == COUNT_EVALS


class _Counted(_Diag):
    """_Diag that counts its evaluations (what a checkpoint must save)."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.calls = 0

    def matrices(self, z, deriv=False):
        self.calls += 1
        return super().matrices(z, deriv)


def test_count_checkpoint_resumes_an_exhausted_walk_without_evaluating_again(tmp_path):
    """A walk that runs out of budget leaves its evaluations; the rerun with a larger budget reads
    them back, evaluates only the rest, and ends exactly as one uninterrupted walk does."""
    lams = np.array([0.0102 + 1.0j, 0.0102 + 1.0001j, 0.5], complex)
    ref_op = _Counted(lams)
    ref = count_unstable(ref_op, (0.01, 4.0, 4.0), max_evals=2000)
    assert ref.status == "converged" and ref.count == 3 and ref.resumed == 0
    ck = str(tmp_path / "walk.npz")
    first_op = _Counted(lams)
    first = count_unstable(first_op, (0.01, 4.0, 4.0), max_evals=60, checkpoint=ck,
                           checkpoint_every=0.0)
    assert first.status == "failed" and first.count is None
    with np.load(ck) as f:
        assert f["z"].size == first_op.calls == first.n_evals
    again_op = _Counted(lams)
    again = count_unstable(again_op, (0.01, 4.0, 4.0), max_evals=2000, checkpoint=ck,
                           checkpoint_every=1e9)           # written only at the end
    assert again.status == "converged" and again.count == ref.count
    assert again.n_evals == ref.n_evals and again.resumed == first.n_evals
    assert again_op.calls == ref.n_evals - first.n_evals
    assert np.array_equal(again.points, ref.points) and np.allclose(again.args, ref.args)
    with np.load(ck) as f:
        assert f["z"].size == ref.n_evals
    # a checkpoint of another operator is not used, and says so
    other = _Counted(lams)
    other.key = "another pulse"
    res = count_unstable(other, (0.01, 4.0, 4.0), max_evals=2000, checkpoint=ck)
    assert res.resumed == 0 and other.calls == ref.n_evals
    assert "another operator" in res.checkpoint_note


def test_count_checkpoint_write_is_atomic(tmp_path, monkeypatch):
    """A write interrupted after the temporary file is opened leaves the previous checkpoint."""
    from slippulse.spectrum import count as cmod
    ck = str(tmp_path / "walk.npz")
    op = _Diag(np.array([0.5], complex))
    cmod.write_checkpoint(ck, cmod.operator_key(op), {0.5 + 1j: (0.25, 2.0 + 0j, -3.5)})

    def broken(fh, **kw):
        fh.write(b"partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(cmod.np, "savez", broken)
    with pytest.raises(KeyboardInterrupt):
        cmod.write_checkpoint(ck, cmod.operator_key(op), {0.1 + 0j: (0.0, 1.0 + 0j, 0.0)})
    monkeypatch.undo()
    cache, note = cmod.read_checkpoint(ck, cmod.operator_key(op))
    assert note == "" and cache == {0.5 + 1j: (0.25, 2.0 + 0j, -3.5)}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.npz"]     # no temporary left


def test_count_checkpoint_in_the_product(tmp_path, pulse12, params):
    """run_spectrum keeps an out-of-budget count's evaluations beside the file and says where;
    the rerun with a larger budget goes on from them, converges as a fresh count does, and
    removes the file."""
    import os
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum.pulse import read_spectrum
    from slippulse.spectrum.family import count_checkpoint_path, SpectrumSettings, run_spectrum
    f = str(tmp_path / "one.h5")
    write_pulse(f, pulse12.to_pulse(), params)
    ck = count_checkpoint_path(f, "td1.2000")
    kw = dict(extra=False, levels=0, level0_points=300, count_box=(0.5, 4.0, 4.0))
    rep = run_spectrum(f, SpectrumSettings(count_evals=16, **kw))
    cnt = rep.results[0].count
    assert cnt.status == "failed" and os.path.exists(ck) and ck in cnt.message
    rep = run_spectrum(f, SpectrumSettings(**kw), overwrite=True)
    cnt = rep.results[0].count
    assert cnt.status == "converged" and cnt.count == 1
    assert 0 < cnt.resumed <= 16 and not os.path.exists(ck)
    assert read_spectrum(f, "td1.2000")["count"] == 1


class _RealDiag(_Diag):
    """A real Q and zeros closed under conjugation: M(σ̄) = conj M(σ)."""

    def __init__(self, lams, symmetric, n=12, seed=0):
        rng = np.random.default_rng(seed)
        self.lams = np.concatenate([lams, 50.0 + rng.uniform(1, 5, n - len(lams))])
        self.Q = rng.normal(size=(n, n))
        self.Qi = np.linalg.inv(self.Q)
        self.conjugate_symmetric = symmetric


def test_count_of_a_conjugate_symmetric_operator_evaluates_one_half():
    lams = np.array([0.5, 2 + 1j, 2 - 1j, 0.0102 + 1.5j, 0.0102 - 1.5j, 6.0, -0.3 + 2j,
                     -0.3 - 2j], complex)
    full = count_unstable(_RealDiag(lams, False), (0.01, 4.0, 4.0))
    half_op = _RealDiag(lams, True)
    calls = []
    orig = half_op.matrices
    half_op.matrices = lambda z, deriv=False: (calls.append(z), orig(z, deriv))[1]
    half = count_unstable(half_op, (0.01, 4.0, 4.0))
    assert full.status == half.status == "converged"
    assert full.count == half.count == 5
    assert np.allclose(full.points, half.points, rtol=0, atol=1e-12)
    assert np.allclose(full.args, half.args)
    assert min(z.imag for z in calls) >= 0.0 and len(calls) == half.n_evals
    assert half.n_evals <= full.n_evals // 2 + 8        # the real-axis points are shared


def test_pulse_operator_is_conjugate_symmetric(pulse12, params):
    from slippulse.spectrum.operators import StabilityOperator
    from slippulse.spectrum.pulse import order4_pulse
    op = StabilityOperator(order4_pulse(pulse12.to_pulse(), params), params,
                           pin_translation=True)
    assert op.conjugate_symmetric
    z = complex(0.3, 2.0) * op.rate_unit
    M, dM = op.matrices(z)
    Mc, dMc = op.matrices(z.conjugate())
    assert np.abs(Mc - M.conj()).max() <= 1e-10 * np.abs(M).max()
    assert np.abs(dMc - dM.conj()).max() <= 1e-10 * np.abs(dM).max()


def test_count_on_workers_walks_the_same_points(tmp_path):
    """Two workers (a Dask LocalCluster of threads): each round's points evaluated at once; the walk visits
    the same points, reads the same arguments and counts the same as the serial walk, and
    evaluates each point once (the checkpoint holds exactly its points)."""
    lams = np.array([0.5, 2 + 1j, 2 - 1j, -1.0], complex)
    serial = count_unstable(_Drift(lams, T=5.0), (0.01, 4.0, 4.0), max_evals=2000)
    ck = str(tmp_path / "walk.npz")
    seen = []
    par = count_unstable(_Drift(lams, T=5.0), (0.01, 4.0, 4.0), max_evals=2000,
                         executor=ExecutorSettings(workers=2, processes=False),
                         checkpoint=ck, progress=seen.append)
    assert serial.status == par.status == "converged"
    assert par.count == serial.count == 3
    assert par.n_evals == serial.n_evals and par.resumed == 0
    assert np.array_equal(par.points, serial.points) and np.allclose(par.args, serial.args)
    with np.load(ck) as f:
        assert f["z"].size == par.n_evals
    assert seen == sorted(seen) and seen[-1] == par.n_evals      # progress only moves forward
    with pytest.raises(ValueError, match="workers=0"):
        ExecutorSettings(workers=0)


@pytest.mark.slow
def test_count_of_the_pulse_operator_on_workers(pulse12, params):
    """The pulse operator survives the trip to two worker processes of a local Dask cluster
    (sent once to each): the same
    count and arguments as the serial walk on the 1.2 τ_min pulse."""
    from slippulse.spectrum.operators import StabilityOperator
    from slippulse.spectrum.pulse import order4_pulse
    op = StabilityOperator(order4_pulse(pulse12.to_pulse(), params), params,
                           pin_translation=True)
    box = (5.0, 34.0, 34.0)
    serial = count_unstable(op, box, max_evals=400)
    par = count_unstable(op, box, max_evals=400, executor=ExecutorSettings(workers=2))
    assert serial.status == par.status == "converged", (serial.message, par.message)
    assert par.count == serial.count == 1
    assert np.array_equal(par.points, serial.points)
    assert np.allclose(par.args, serial.args, rtol=0, atol=1e-8)


def test_guess_starts_the_search_where_the_default_shifts_find_nothing(tmp_path, pulse12, params,
                                                                      monkeypatch):
    """run_spectrum(guess=S): the first pulse's search starts at s L/c_p = S. With the default
    shifts removed the search finds nothing; from the guess it finds the 1.2 τ_min pulse's mode
    (≈ 22.65 c_p/L). The CLI refuses a guess outside (0, 100] in one line."""
    import subprocess
    import sys
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum import pulse as spectrum
    from slippulse.spectrum.family import SpectrumSettings, run_spectrum
    f = str(tmp_path / "one.h5")
    write_pulse(f, pulse12.to_pulse(), params)
    monkeypatch.setattr(spectrum, "DEFAULT_SHIFTS", ())
    s = SpectrumSettings(extra=False, levels=0, level0_points=300)
    blind = run_spectrum(f, s, overwrite=True).results[0]
    assert blind.sigmas.size == 0
    found = run_spectrum(f, s, overwrite=True, guess=20.0).results[0]
    assert found.status == "converged" and found.sigmas.size == 1
    assert abs(found.leading / found.rate_unit - 22.65) < 0.1
    r = subprocess.run([sys.executable, "-m", "slippulse", "steady", "stability", f,
                        "--guess", "-1"], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "guess=-1.0" in r.stderr


def test_the_count_finds_the_leading_eigenvalue_a_tracked_start_missed(tmp_path, params):
    """The two-hump pulse at 1.2 τ_min (N = 500) has three unstable eigenvalues, 44.6, 15.0 and
    1.38 c_p/L. A search started at 1.4 finds 1.38 and calls it leading; with a count over
    [0.5, 70]², the count's zeros, polished, give all three, and the search is made again from
    the largest (``leading_from = "count"``)."""
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum.family import SpectrumSettings, run_spectrum
    from slippulse.spectrum.pulse import read_spectrum
    from slippulse.steady.branch_search import GUESS_SETS, search
    rep = search(params, 1.2, GUESS_SETS["quick"](), n_points=500, check=False)
    two = [f.pulse for f in rep.found if f.pulse.extra["n_humps"] == 2][0]
    leads = {}
    for box in (None, (0.5, 70.0, 70.0)):
        f = str(tmp_path / f"two{box is None}.h5")
        write_pulse(f, two, params)
        run_spectrum(f, SpectrumSettings(extra=False, levels=0, level0_points=500,
                                         count_box=box), guess=1.4)
        leads[box is None] = st = read_spectrum(f, two.label)
    assert leads[True]["leading_s_per_L"] == pytest.approx(1.379, rel=1e-2)   # what it is for
    st = leads[False]
    assert st["leading_from"] == "count" and st["count"] == 3
    located = np.sort(st["count_located_real"])[::-1]
    assert located.size == 3 and np.all(st["count_located_imag"] == 0.0)
    assert located == pytest.approx([44.6, 14.99, 1.379], rel=2e-3)
    assert st["leading_s_per_L"] == pytest.approx(located[0], rel=1e-9)


class _Positive(_Diag):
    """_Diag whose M, like the pulse operators' kernel tables, exists only for Re σ > 0."""

    n = 12
    conjugate_symmetric = True

    def __init__(self, lams):
        super().__init__(lams, n=self.n)
        self.lams = self.lams.real.astype(complex)        # real zeros: M(σ̄) = conj M(σ)
        self.Q, self.Qi = self.Q.real, np.linalg.inv(self.Q.real)

    def matrices(self, z, deriv=True):
        if not complex(z).real > 0.0:
            raise ValueError(f"sigma={z}: needs Re sigma > 0")
        return super().matrices(z, True)


def test_the_polish_shifts_an_estimate_left_of_the_box_into_it(monkeypatch):
    """An estimate of the moments can fall outside the box, left of the analytic half-plane (the
    two-hump pulse at 1.046 τ_min, three zeros in a box of 70 c_p/L: one at −69). The polish
    starts from the nearest point of the box instead of failing there."""
    import slippulse.spectrum.count as count
    from slippulse.spectrum.pulse import polish_located
    op = _Positive(np.array([2.0, 3.5]))
    cnt = count_unstable(op, (0.1, 4.0, 4.0))
    assert cnt.count == 2
    # −0.2 lies within the tenth of the box by which estimates are taken, left of Re σ = 0
    monkeypatch.setattr(count, "zeros_in_box", lambda c, known=(): np.array([-0.2 + 0j, 3.4 + 0j]))
    found, _ = polish_located(op, cnt)
    assert np.sort(found.real) == pytest.approx([2.0, 3.5], abs=1e-8)
    assert np.sort(cnt.located.real) == pytest.approx([2.0, 3.5], abs=1e-8)
