"""Fold and branch-point test functions and their locator (steady/bifurcation.py), on small
systems whose folds and branch points are known exactly, and on a pulse."""
import math

import numpy as np
import pytest

from slippulse.steady.bifurcation import (LocateError, ScanRow, events, indicators, locate,
                                          lu_det, pulse_tests)


class Pitchfork:
    """F(x, z; λ) = (x³ − λx + μ, z − x² − λ): a pitchfork at λ = 0, x = 0 for μ = 0; for
    μ ≠ 0 the x > 0 branch (μ > 0) folds at x = (μ/2)^(1/3), λ = 3 (μ/2)^(2/3)."""

    def __init__(self, mu=0.0):
        self.mu = mu

    def residual_and_jacobian(self, X):
        x, z, lam = X
        r = np.array([x ** 3 - lam * x + self.mu, z - x * x - lam])
        J = np.array([[3 * x * x - lam, 0.0, -x], [-2 * x, 1.0, -1.0]])
        return r, J


class SCurve:
    """F(x, z; λ) = (x³ − x − λ, 2z − sin x): folds at x = ±1/√3, λ = ∓2/(3√3)."""

    def residual_and_jacobian(self, X):
        x, z, lam = X
        r = np.array([x ** 3 - x - lam, 2 * z - math.sin(x)])
        J = np.array([[3 * x * x - 1, 0.0, -1.0], [-math.cos(x), 2.0, 0.0]])
        return r, J


def _scurve_point(x):
    return np.array([x, 0.5 * math.sin(x), x ** 3 - x])


def test_lu_det_sign_and_log_match_numpy():
    rng = np.random.default_rng(1)
    for _ in range(20):
        M = rng.standard_normal((7, 7))
        s, lg, _ = lu_det(M)
        s2, lg2 = np.linalg.slogdet(M)
        assert s == int(s2) and lg == pytest.approx(lg2, rel=1e-12)


def test_cramer_identity_det_A_equals_det_B_times_t_lambda():
    rng = np.random.default_rng(2)
    J = rng.standard_normal((9, 10))
    v = indicators(J)
    assert v.cramer_defect < 1e-10
    # the tangent is a null vector of unit length
    assert np.linalg.norm(J @ v.tangent) < 1e-12 and np.linalg.norm(v.tangent) == pytest.approx(1)


def test_fold_located_on_s_curve():
    xa, xb = _scurve_point(0.3), _scurve_point(0.9)
    bif = locate(SCurve(), xa, xb)
    assert bif.kind == "fold"
    assert bif.x[0] == pytest.approx(1 / math.sqrt(3), abs=1e-8)
    assert bif.parameter == pytest.approx(-2 / (3 * math.sqrt(3)), abs=1e-10)


def test_pitchfork_located_on_trivial_branch():
    xa, xb = np.array([0.0, -0.5, -0.5]), np.array([0.0, 0.7, 0.7])
    bif = locate(Pitchfork(), xa, xb)
    assert bif.kind == "branch point"
    assert abs(bif.parameter) < 1e-10


def test_imperfect_pitchfork_is_a_fold_not_a_branch_point():
    mu = 0.01
    sys_ = Pitchfork(mu)

    def point(x):
        lam = x * x + mu / x
        return np.array([x, x * x + lam, lam])

    bif = locate(sys_, point(0.12), point(0.25))
    xf = (mu / 2) ** (1 / 3)
    assert bif.kind == "fold"
    assert bif.x[0] == pytest.approx(xf, rel=1e-7)
    assert bif.parameter == pytest.approx(3 * (mu / 2) ** (2 / 3), rel=1e-9)


def test_locate_refuses_solutions_too_far_apart():
    """Far apart, the branch is not a graph over the chord (it leaves x = 0.05 at 109° from it)
    and a sign change of det[J; d] would not mean a branch point: refused."""
    mu = 0.01

    def point(x):
        lam = x * x + mu / x
        return np.array([x, x * x + lam, lam])

    with pytest.raises(LocateError, match="too far apart"):
        locate(Pitchfork(mu), point(0.05), point(0.5))


def test_locate_refuses_a_regular_stretch():
    with pytest.raises(LocateError):
        locate(SCurve(), _scurve_point(0.7), _scurve_point(1.2))


def _rows(system, points, labels=None):
    rows, prev = [], None
    for i, X in enumerate(points):
        nxt = points[min(i + 1, len(points) - 1)]
        prv = points[max(i - 1, 0)]
        orient = np.zeros(X.size)
        orient[-1] = 1.0 if nxt[-1] == prv[-1] else 0.0
        orient = nxt - prv
        v = indicators(system.residual_and_jacobian(X)[1], orient=orient)
        rows.append(ScanRow(f"p{i}", X[-1], 0.0, 0.0, 2, 0.0, v))
    return rows


def test_scan_events_find_the_pitchfork_and_the_folds():
    lam = np.linspace(-1, 1, 21) + 0.025           # λ = 0 between two points
    pts = [np.array([0.0, l, l]) for l in lam]
    ev = events(_rows(Pitchfork(), pts))
    kinds = [(e.kind, e.between) for e in ev if e.kind != "sigma minimum"]
    assert kinds == [("branch point", ("p9", "p10"))]
    xs = np.linspace(-1.0, 1.0, 20)                 # ±1/√3 = ±0.577 between points
    ev = events(_rows(SCurve(), [_scurve_point(x) for x in xs]))
    folds = [e.between for e in ev if e.kind == "fold"]
    assert folds == [("p4", "p5"), ("p14", "p15")]
    assert not [e for e in ev if e.kind == "branch point"]


def test_pulse_indicators_regular_at_1p2(params, pulse12):
    v, res = pulse_tests(pulse12.to_pulse(), params, orient_scalars=(1.0, -1.0))
    assert res < 1e-11                                # the rebuilt system holds the stored pulse
    assert v.cramer_defect < 1e-6
    assert v.fold_sign != 0 and v.t_param < 0         # τ_d falls as β rises: no fold here
    assert v.sigma[0] > 1e-8 and v.sigma[0] < v.sigma[1]


# --------------------------------------------------------------------------- referee checks
def _fake_pulse(q, beta, slip, params):
    """A pulse-shaped record with total slip `slip` (a box of slip rate over 1 m)."""
    from slippulse.core.h5io import Pulse
    xi = np.linspace(-2.0, 1.0, 301)
    v_st = 1e-7
    c = beta * params.c_s
    v = np.where((xi > -1.0) & (xi < 0.0), v_st + slip * c, v_st)
    z = np.zeros_like(xi)
    tm = params.tau_min
    return Pulse(xi=xi, v=v, phi=np.full_like(xi, 1e-3), tau=np.full_like(xi, q * tm),
                 residual=z, tau_d_ratio=q, tau_d=q * tm, tau_min=tm,
                 beta=beta, c_p=c, L=1.0, L_tilde=1.0, v_stick=v_st, v_max=float(v.max()),
                 max_residual=0.0, converged=True, n_points=xi.size, wall_time=0.0)


def test_slip_criterion_sign_and_agreement(params):
    from slippulse.steady.analysis import slip_criterion
    # b = (q − 1.1)² has db/dq < 0 below 1.1 and > 0 above; β rises as q falls
    qs = [1.2, 1.15, 1.12, 1.08, 1.05, 1.02]
    ps = [_fake_pulse(q, 0.5 - q / 3, (q - 1.1) ** 2 + 0.01, params) for q in qs]
    rates = {1.15: (2.0, 0.1), 1.05: (0.5, 0.1), 1.08: (0.01, 0.1)}
    rows = {r["tau_d_ratio"]: r for r in slip_criterion(ps, params, rates)}
    # exact derivative 2 (q − 1.1) (quadratic: three-point differences are exact), to trapezoid error
    for q in qs[1:-1]:
        assert rows[q]["db_dq"] == pytest.approx(2 * (q - 1.1), rel=2e-2, abs=2e-4)
    assert rows[1.05]["predicted"] == "unstable" and rows[1.05]["agree"] is True
    assert rows[1.15]["predicted"] == "stable" and rows[1.15]["agree"] is False
    assert rows[1.08]["s_sign"] == "unresolved" and rows[1.08]["agree"] is None
    assert rows[1.12]["s_sign"] is None


def test_paper_range_fit_recovers_constants(tmp_path, params):
    """Pulses placed exactly on Eqs. 3–4 with known constants: the fit over 1.015–1.2 returns them."""
    from slippulse.steady.analysis import paper_range_fit
    from slippulse.steady.fits import scaling_law
    from slippulse.core.h5io import write_pulse
    path = str(tmp_path / "fam.h5")
    qs = np.linspace(1.015, 1.2, 8)
    b, Lt = scaling_law(qs, 1.0091, 1.3, 0.6, params)
    for q, bb, ll in zip(qs, b, Lt):
        p = _fake_pulse(float(q), float(bb), 1e-4, params)
        p.L = float(ll * params.L_Gc)
        write_pulse(path, p, params)
    fit = paper_range_fit(path)
    assert fit["both"]["tau_star"] == pytest.approx(1.0091, abs=1e-7)
    assert fit["both"]["a_v"] == pytest.approx(1.3, rel=1e-5)
    assert fit["both"]["a_G"] == pytest.approx(0.6, rel=1e-5)
    assert fit["paper"]["tau_star"] == 1.0087 and fit["paper_rms"] > 0.01


def test_null_vector_bordered_branch_matches_qr(monkeypatch):
    """The bordered-LU null vector (large systems) is the QR one up to sign."""
    import slippulse.steady.bifurcation as bif
    rng = np.random.default_rng(5)
    J = rng.standard_normal((30, 31))
    t_qr = bif.null_vector(J)
    monkeypatch.setattr(bif, "QR_MAX", 10)
    t_lu = bif.null_vector(J)
    assert abs(abs(t_qr @ t_lu) - 1) < 1e-12 and np.linalg.norm(J @ t_lu) < 1e-12


def test_cli_bifurcations_prints_and_stores_the_test_functions(tmp_path, params, pulse12):
    import cli_inproc
    from slippulse.core.h5io import read_pulse, write_pulse
    path = str(tmp_path / "one.h5")
    write_pulse(path, pulse12.to_pulse(), params)
    r = cli_inproc.run(["steady", "bifurcations", path, "--write", "-q"])
    assert r.returncode == 0, r.stderr
    assert "0 folds" in r.stdout and "0 branch points" in r.stdout
    p, _ = read_pulse(path, "td1.2000")
    assert p.extra["bif_fold_sign"] in (-1, 1) and p.extra["bif_sigma1"] > 0
    r = cli_inproc.run(["steady", "bifurcations", path, "--labels", "td1.1000", "-q"])
    assert r.returncode == 2 and "td1.1000" in r.stderr


def test_locate_says_when_it_did_not_converge():
    bif = locate(SCurve(), _scurve_point(0.3), _scurve_point(0.9), max_eval=2)
    assert bif.kind == "fold" and not bif.converged
    assert locate(SCurve(), _scurve_point(0.3), _scurve_point(0.9)).converged


def test_scan_reads_the_stored_count_of_real_unstable_eigenvalues(steady12_with_spectrum):
    from slippulse.steady.bifurcation import scan
    rows, ev = scan(steady12_with_spectrum)
    assert len(rows) == 1 and rows[0].unstable_count == 1 and not ev


def test_family_stores_the_test_functions_of_every_pulse_and_reports_their_events(tmp_path):
    """``steady family`` stores the test functions with each pulse it writes, the tangent
    oriented along the march (t_q < 0 on a family continued down in τ_d without a fold), and
    reports their events; a stored sign change of t_q is read back as a fold."""
    import h5py
    import cli_inproc
    from slippulse.core.h5io import list_pulses, read_pulse
    from slippulse.steady.bifurcation import stored_rows
    path = tmp_path / "fam.h5"
    r = cli_inproc.run(["steady", "family", "--from", "1.2", "--to", "1.16", "--step", "0.02",
                        "--out", path, "-q"])
    assert r.returncode == 0, r.stderr
    assert "test functions: 3 pulses: 0 folds" in r.stdout and "0 branch points" in r.stdout
    labels = list_pulses(str(path))
    for lab in labels:
        p, _ = read_pulse(str(path), lab)
        assert p.extra["bif_t_q"] < 0 and p.extra["bif_fold_sign"] in (-1, 1)
        assert 0 < p.extra["bif_sigma1"] <= p.extra["bif_sigma2"]
    rows = stored_rows(str(path))
    assert [r.label for r in rows] == sorted(labels, key=lambda lab: read_pulse(str(path), lab)[0].beta)
    assert not [e for e in events(rows) if e.kind in ("fold", "branch point")]
    with h5py.File(path, "a") as h5:                   # the middle pulse's tangent turned back
        h5["pulses"][rows[1].label].attrs["bif_t_q"] = -rows[1].values.t_param
    kinds = [e.kind for e in events(stored_rows(str(path)))]
    assert kinds.count("fold") == 2


def test_null_vector_from_the_lu_of_A_is_the_qr_one_even_at_a_fold(
        params, pulse12):
    """null_vector_from_lu: the unit null vector of J = [A c] from the LU of A is the QR one up to
    sign, on a random J and on the 1.2 τ_min pulse's extended Jacobian (N = 700, scaled as the
    test functions scale it); at a fold (A singular) it still gives J's null vector, or None
    (indicators then takes the QR)."""
    import scipy.linalg as sla
    from slippulse.steady.bifurcation import null_vector, null_vector_from_lu, pulse_system
    rng = np.random.default_rng(7)
    J = rng.standard_normal((40, 41))
    t = null_vector_from_lu(J, sla.lu_factor(J[:, :40]))
    assert abs(abs(t @ null_vector(J)) - 1) < 1e-12
    prob, x, scale = pulse_system(pulse12.to_pulse(), params)
    Js = prob.residual_and_jacobian(x)[1] * scale[None, :]
    n = Js.shape[0]
    t = null_vector_from_lu(Js, sla.lu_factor(Js[:, :n]))
    assert abs(abs(t @ null_vector(Js)) - 1) < 1e-12 and np.linalg.norm(Js @ t) < 1e-10
    S = J.copy()
    S[:, 3] = S[:, 5]                           # a fold: A singular, J still of rank 40, t_λ = 0
    with np.errstate(all="ignore"):
        t = null_vector_from_lu(S, sla.lu_factor(S[:, :40]))
    # A⁻¹c blows up along A's null direction, which is J's: the normalised t is still right
    assert t is None or (abs(abs(t @ null_vector(S)) - 1) < 1e-12 and abs(t[-1]) < 1e-12)
    v = indicators(S)
    assert abs(v.t_param) < 1e-12                 # the fold shows as t_λ = 0
    assert np.linalg.norm(S @ v.tangent) < 1e-12 and abs(v.tangent @ null_vector(S)) > 1 - 1e-12


def test_bordered_test_functions_are_those_of_the_factored_bordered_matrix(params, monkeypatch):
    """The test functions of a pulse (1.05 τ_min, above the dense-SVD size, columns scaled as
    along a family): det B by Cramer from the LU of A and B⁻¹ by bordering give the sign,
    ln|det| and two smallest singular values of B factored itself (BORDER_MIN above |t_λ|)."""
    from slippulse.steady import bifurcation as bf
    pulse = _pulse(params, 1.05)
    bordered, _ = bf.pulse_tests(pulse, params)
    assert abs(bordered.t_param) >= bf.BORDER_MIN and pulse.xi.size > bf.DENSE_SVD_MAX
    monkeypatch.setattr(bf, "BORDER_MIN", 2.0)
    factored, _ = bf.pulse_tests(pulse, params)
    assert bordered.bordered_sign == factored.bordered_sign != 0
    assert bordered.bordered_logdet == pytest.approx(factored.bordered_logdet, abs=1e-8)
    assert bordered.sigma == pytest.approx(factored.sigma, rel=1e-9)


def _pulse(params, q):
    from slippulse.steady.solver import solve_pulse
    return solve_pulse(params, q, n_points=700).to_pulse()


def test_a_sign_change_across_a_grid_change_is_decided_on_one_grid(params, tmp_path):
    """Neighbours on grids of 500 and 601 points: their own det B signs differ (the sign is a
    property of one discrete system), yet re-solved on one grid they agree: no branch point."""
    from slippulse.steady.bifurcation import across_grid_change
    from slippulse.steady.solver import solve_pulse
    pa = solve_pulse(params, 1.2, n_points=500).to_pulse()
    pb = solve_pulse(params, 1.198, n_points=601).to_pulse()
    orient = (math.log(pb.beta / pa.beta), pb.tau_d_ratio - pa.tau_d_ratio)
    sa = pulse_tests(pa, params, (orient[0] * pa.beta, orient[1]), False)[0].bordered_sign
    sb = pulse_tests(pb, params, (orient[0] * pb.beta, orient[1]), False)[0].bordered_sign
    assert sa * sb < 0
    assert across_grid_change(pa, pb, params) is None
    assert across_grid_change(pb, pa, params) is None
    # a family run decides it when it writes the second pulse, and the report reads it
    from slippulse.steady.bifurcation import FamilyMonitor
    mon = FamilyMonitor(params)
    attrs = [mon(None, p) for p in (pa, pb)]
    assert "bif_across_grid" not in attrs[0] and attrs[1]["bif_across_grid"] == "kept"
    rows = [ScanRow(p.label, p.tau_d_ratio, p.beta, p.L, p.n_points, 0.0,
                    pulse_tests(p, params, (1.0, -1.0), False)[0], across=a.get("bif_across_grid"))
            for p, a in zip((pa, pb), attrs)]
    assert rows[0].values.bordered_sign * rows[1].values.bordered_sign < 0
    assert not events(rows)
    rows[1].across = None
    assert [e.kind for e in events(rows)] == ["not comparable"]
    # the command: a file written without the family's decision leaves the pair undecided and
    # names --locate, which decides it
    import cli_inproc
    from slippulse.core.h5io import write_pulse
    path = str(tmp_path / "two.h5")
    for p in (pa, pb):
        p.extra.pop("bif_across_grid", None)
        write_pulse(path, p, params)
    r = cli_inproc.run(["steady", "bifurcations", path, "-q"])
    assert r.returncode == 0 and "1 not decided" in r.stdout and "--locate" in r.stdout
    r = cli_inproc.run(["steady", "bifurcations", path, "--locate", "-q"])
    assert r.returncode == 0 and "0 not decided" in r.stdout
    assert "1 det B sign changes across a change of N that keep the sign" in r.stdout


def test_the_monitor_hands_its_tangent_to_the_grid_check(params):
    """A natural step's pulse (fixed τ_d, no tangent) gets the family tangent from the fold
    test (the β column rescaled), so that its grid check needs no dense solve: the same unit
    tangent as the check's own solve, and the same check figures."""
    from slippulse.steady.bifurcation import FamilyMonitor
    from slippulse.steady.continuation import family_tangent, grid_change
    from slippulse.steady.continuation.arclength import unit_tangent
    from slippulse.steady.continuation.gridcheck import as_both
    from slippulse.steady.solver import solve_pulse
    sol = solve_pulse(params, 1.2, n_points=500)
    assert sol.stats.converged and sol.tangent is None
    both = as_both(params, sol)
    own = family_tangent(both.problem, both.x, (1.0, 0.0, 1.0))
    FamilyMonitor(params)(sol, sol.to_pulse())
    handed = as_both(params, sol)
    assert handed.tangent is not None and handed.tangent.shape == handed.x.shape
    t = handed.tangent if handed.tangent[-2] >= 0 else -handed.tangent
    # the same null vector to round-off relative to its largest component (its q component,
    # 1e-8 of that, is the least well determined part of either)
    assert np.max(np.abs(unit_tangent(t, sol.beta, 1.0) - own)) <= 1e-9 * np.max(np.abs(own))
    _, db_own, dl_own = grid_change(params, both, 500, nested=True)
    _, db, dl = grid_change(params, handed, 500, nested=True)
    assert db == pytest.approx(db_own, rel=1e-7, abs=1e-15)
    assert dl == pytest.approx(dl_own, rel=1e-7, abs=1e-15)


class SignStep:
    """F(x, z; λ) = (x − λ, s(x)(z − λ)), s(x) = sign(x − 0.3): the solutions are the regular line
    x = z = λ, but det A = s(x) changes sign at x = 0.3 by a jump, with no zero."""

    def residual_and_jacobian(self, X):
        x, z, lam = X
        s = 1.0 if x > 0.3 else -1.0
        r = np.array([x - lam, s * (z - lam)])
        J = np.array([[1.0, 0.0, -1.0], [0.0, s, -s]])
        return r, J


def test_a_test_function_that_jumps_sign_is_not_located_as_a_zero():
    bif = locate(SignStep(), np.zeros(3), np.ones(3))
    assert bif.jump and bif.theta == pytest.approx(0.3, abs=1e-8)
    assert abs(bif.residual_test) > 0.1
    # a simple zero is not a jump
    assert not locate(SCurve(), _scurve_point(0.3), _scurve_point(0.9)).jump
    assert not locate(Pitchfork(), np.array([0.0, -0.5, -0.5]), np.array([0.0, 0.7, 0.7])).jump


def test_transversality_is_zero_at_a_pitchfork_and_not_at_a_fold():
    from slippulse.steady.null_modes import transversality
    # the pitchfork at λ = 0, x = 0: ψ = (1, 0), ∂F/∂λ = (−x, −1) = (0, −1)
    _, J = Pitchfork().residual_and_jacobian(np.array([0.0, 0.0, 0.0]))
    assert transversality(J) < 1e-12
    # the S-curve's fold at x = 1/√3: ψ = (1, 0), ∂F/∂λ = (−1, 0)
    xf = 1 / math.sqrt(3)
    _, J = SCurve().residual_and_jacobian(_scurve_point(xf))
    assert transversality(J) == pytest.approx(1.0, abs=1e-10)
    # the imperfect pitchfork's fold: ψ = (1, 0), ∂F/∂λ = (−x_f, −1): cos = x_f/√(1 + x_f²)
    mu = 0.01
    xf = (mu / 2) ** (1 / 3)
    lam = 3 * (mu / 2) ** (2 / 3)
    _, J = Pitchfork(mu).residual_and_jacobian(np.array([xf, xf * xf + lam, lam]))
    assert transversality(J) == pytest.approx(xf / math.sqrt(1 + xf * xf), rel=1e-8)
