"""Deflated Newton (steady/deflation.py), the search for every pulse at one τ_d
(steady/branch_search.py) and its command ``slippulse steady branches``."""
import math
import os
from types import SimpleNamespace

import numpy as np
import pytest

import cli_inproc
from slippulse.core.h5io import list_pulses, read_pulse, write_pulse
from slippulse.steady.deflation import Deflation, deflated_newton


class Cubic:
    """F(x) = (x − 1)(x − 2)(x + 3) and z − x²: three roots, known exactly."""

    def residual(self, X):
        x, z = X
        return np.array([(x - 1) * (x - 2) * (x + 3), z - x * x])

    def residual_and_jacobian(self, X):
        x, z = X
        d = (x - 2) * (x + 3) + (x - 1) * (x + 3) + (x - 1) * (x - 2)
        return self.residual(X), np.array([[d, 0.0], [-2 * x, 1.0]])

    def valid(self, X):
        return bool(np.all(np.isfinite(X)))


def test_deflation_gradient_matches_finite_differences():
    rng = np.random.default_rng(3)
    D = Deflation(p=2.0, sigma=0.5)
    for _ in range(2):
        D.add(rng.standard_normal(5), rng.uniform(0.5, 2.0, 5))
    x = rng.standard_normal(5)
    M, g = D(x)
    h = 1e-6
    fd = np.array([(D(x + h * e)[0] - D(x - h * e)[0]) / (2 * h) for e in np.eye(5)])
    assert np.allclose(g, fd, rtol=1e-6, atol=1e-9)


def test_sherman_morrison_step_is_newton_on_the_deflated_residual():
    """δ = δ₀/(1 − ∇M·δ₀/M) solves (M J + F ∇Mᵀ) δ = −M F."""
    rng = np.random.default_rng(4)
    J, F = rng.standard_normal((6, 6)), rng.standard_normal(6)
    D = Deflation()
    D.add(rng.standard_normal(6), np.ones(6))
    x = rng.standard_normal(6)
    M, g = D(x)
    d0 = np.linalg.solve(J, -F)
    d = d0 / (1 - g @ d0 / M)
    assert np.allclose((M * J + np.outer(F, g)) @ d, -M * F)


def test_deflated_newton_finds_all_three_roots_from_one_guess():
    D = Deflation(p=2.0, sigma=1.0)
    roots = []
    for _ in range(4):
        res = deflated_newton(Cubic(), np.array([0.1, 0.0]), D, tol=1e-12, max_iter=100,
                              max_dy=10.0, n_free=0)
        if not res.converged:
            break
        roots.append(res.x[0])
        D.add(res.x, np.ones(2))
    assert sorted(np.round(roots, 10)) == [-3.0, 1.0, 2.0]


def test_search_finds_the_family_pulse_and_the_two_hump_pulse(params):
    """At 1.2 τ_min the quick guesses (the built-in one, a two-pulse state 1.4 m apart) reach the
    family pulse and the bound state of two pulses (docs/steady.md §2), at N = 500."""
    from slippulse.steady.branch_search import GUESS_SETS, search
    rep = search(params, 1.2, GUESS_SETS["quick"](), n_points=500, check=False)
    got = sorted((f.pulse.extra["n_humps"], f.pulse.beta, f.pulse.L) for f in rep.found)
    assert [g[0] for g in got] == [1, 2]
    assert got[0][1] == pytest.approx(0.0072417, rel=2e-3) and got[0][2] == pytest.approx(1.074, rel=5e-3)
    assert got[1][1] == pytest.approx(0.0054863, rel=2e-3) and got[1][2] == pytest.approx(2.071, rel=5e-3)
    # the built-in guess is deflated once it has its pulse: it then fails, it does not re-find it
    assert rep.reached[0] == [0]


@pytest.mark.parametrize("args,name", [
    (["--tau-d", "1.0"], "tau-d"), (["--tau-d", "1.34"], "tau-d"), (["--tau-d", "x"], "tau-d"),
    (["--tau-d", "1.2", "--p", "0.5"], "p="), (["--tau-d", "1.2", "--points", "10"], "points")])
def test_cli_bad_input_one_line_exit_2_no_file(tmp_path, args, name):
    out = tmp_path / "b.h5"
    r = cli_inproc.run(["steady", "branches", *args, "--out", out, "-q"])
    assert r.returncode == 2, r.stderr
    assert name in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_cli_refuses_a_missing_label_and_a_file_of_other_parameters(tmp_path, params, pulse12):
    src = str(tmp_path / "src.h5")
    write_pulse(src, pulse12.to_pulse(), params)
    out = tmp_path / "b.h5"
    r = cli_inproc.run(["steady", "branches", "--tau-d", "1.2", "--guesses", "none", "--guess",
                        f"{src}:td1.1000", "--out", out, "-q"])
    assert r.returncode == 2 and "td1.1000" in r.stderr and not out.exists()
    assert len(r.stderr.strip().splitlines()) == 1
    r = cli_inproc.run(["steady", "branches", "--tau-d", "1.2", "--guesses", "none", "--guess",
                        f"{src}:td1.2000", "--set", "params.sigma=2e6", "--out", out, "-q"])
    assert r.returncode == 2 and "sigma" in r.stderr and not out.exists()
    r = cli_inproc.run(["steady", "branches", "--tau-d", "1.2", "--out", src, "--overwrite",
                        "--set", "params.sigma=2e6", "-q"])
    assert r.returncode == 2 and "other parameters" in r.stderr


def test_cli_writes_each_solution_under_its_own_label(tmp_path, params, pulse12):
    """From a stored pulse only: one solution, written with its hump count and grid check."""
    src = str(tmp_path / "src.h5")
    write_pulse(src, pulse12.to_pulse(), params)
    out = str(tmp_path / "b.h5")
    r = cli_inproc.run(["steady", "branches", "--tau-d", "1.2", "--guesses", "none", "--guess",
                        f"{src}:td1.2000", "--points", "500", "--no-grid-check", "--out", out,
                        "-q"])
    assert r.returncode == 0, r.stderr
    assert list_pulses(out) == ["td1.2000"]
    p, _ = read_pulse(out, "td1.2000")
    assert p.extra["n_humps"] == 1 and p.extra["reached_by"] == "0"
    assert p.beta == pytest.approx(0.0072417, rel=2e-3)
    # the file is written whole under a temporary name and renamed: nothing of that is left
    assert sorted(f.name for f in tmp_path.iterdir() if "tmp" in f.name) == []


def test_solution_labels_parse_to_the_same_tau_d():
    from slippulse.cli.branches import solution_label
    from slippulse.core.h5io import label_ratio
    labs = [solution_label(1.2, k) for k in range(3)]
    assert labs == ["td1.2000", "td1.20000", "td1.200000"]
    assert all(label_ratio(lab) == 1.2 for lab in labs)


@pytest.mark.parametrize("state", [0.0, 1.0])
def test_trace_follows_the_main_family_down_from_1p2(params, pulse12, state):
    """Three pseudo-arclength steps down from the 1.2 pulse, the arclength in (ln β, q) alone or
    with the shape counted: τ_d falls, β rises, one hump, no fold or branch point; the last point
    is the pulse a fixed-τ_d solve gives there."""
    from slippulse.steady.branch_trace import ArcMetric, TraceSettings, trace
    from slippulse.steady.solver import solve_on_grid
    tr = trace(params, pulse12.to_pulse(), TraceSettings(direction=-1, max_steps=3,
                                                         metric=ArcMetric(state)))
    q = [p.q for p in tr.points]
    b = [p.beta for p in tr.points]
    assert len(q) == 4 and all(np.diff(q) < 0) and all(np.diff(b) > 0)
    assert {p.humps for p in tr.points} == {1} and not tr.events
    last = tr.pulses[-1]
    prob, x, st = solve_on_grid(params, last.tau_d_ratio, last.xi, np.log(last.v), 1.05 * last.beta)
    assert st.converged and x[-1] == pytest.approx(last.beta, rel=1e-9)


def test_cli_branch_trace_writes_each_point_and_refuses_bad_input(tmp_path, params, pulse12):
    """One step each way from the 1.2 pulse (--direction both): three pulses in one file, the
    start written once; along the trace position (step signed by direction) τ_d rises and β
    falls, t_q is oriented along each march (negative down, positive up) and each pulse carries
    its grid check and the arclength's metric; a missing label, a ds outside [ds-min, ds-max]
    and a negative --arc-state are one-line refusals with no file."""
    src = str(tmp_path / "src.h5")
    write_pulse(src, pulse12.to_pulse(), params)
    out = str(tmp_path / "t.h5")
    r = cli_inproc.run(["steady", "branch-trace", f"{src}:td1.2000", "--direction", "both",
                        "--max-steps", "1", "--ds", "0.05", "--grid-check", "--out", out, "-q"])
    assert r.returncode == 0, r.stderr
    labs = list_pulses(out)
    assert len(labs) == 3
    pulses = sorted((read_pulse(out, lab)[0] for lab in labs),
                    key=lambda p: p.extra["trace_position"])
    assert [p.extra["trace_position"] for p in pulses] == [-1, 0, 1]
    assert all(np.diff([p.tau_d_ratio for p in pulses]) > 0)
    assert pulses[1].tau_d_ratio == pytest.approx(1.2, abs=1e-12)
    assert all(np.diff([p.beta for p in pulses]) < 0)
    assert pulses[0].extra["trace_t_q"] < 0 < pulses[2].extra["trace_t_q"]
    assert all(p.extra["grid_check_converged"] for p in pulses)
    assert all(abs(p.extra["grid_check_dq"]) < 1e-6 for p in pulses)
    assert "2 points traced down" in r.stdout and "2 points traced up" in r.stdout
    assert pulses[0].extra["trace_arc_metric"] == "(ln beta, q/0.04)"
    for bad, name in ((f"{src}:td1.1000", "td1.1000"), (f"{src}:td1.2000", "ds="),
                      (f"{src}:td1.2000", "arc-state=")):
        extra = {"ds=": ["--ds", "0.5"], "arc-state=": ["--arc-state", "-1"]}.get(name, [])
        o2 = tmp_path / "bad.h5"
        r = cli_inproc.run(["steady", "branch-trace", bad, "--direction", "down", *extra,
                            "--out", o2, "-q"])
        assert r.returncode == 2 and name in r.stderr and not o2.exists(), r.stderr
        assert len(r.stderr.strip().splitlines()) == 1


def test_a_killed_branch_trace_is_resumed_by_the_same_command(tmp_path, params, pulse12):
    """A trace killed in its third write (SIGKILL once the write's journal is on disk) keeps
    three pulses; the same command resumes it from its last one, numbering on, and stops at
    --max-steps in all; run once more it does nothing, and with a larger --max-steps it goes on.
    A file of another trace (another --arc-state) is refused in one line and left as it was."""
    import os
    import subprocess
    import sys
    src = str(tmp_path / "src.h5")
    write_pulse(src, pulse12.to_pulse(), params)
    out = str(tmp_path / "t.h5")
    args = ["steady", "branch-trace", f"{src}:td1.2000", "--direction", "down", "--ds", "0.05",
            "--out", out, "-q"]
    env = dict(os.environ, SLIPPULSE_KILL_AT="journal_written:2")
    r = subprocess.run([sys.executable, "-m", "slippulse.cli", *args, "--max-steps", "4"],
                       env=env, capture_output=True, text=True)
    assert r.returncode == -9, r.stderr
    before = {lab: read_pulse(out, lab)[0] for lab in list_pulses(out)}
    assert sorted(p.extra["trace_step"] for p in before.values()) == [0, 1, 2]
    r = cli_inproc.run([*args, "--max-steps", "4"])
    assert r.returncode == 0, r.stderr
    assert "resumed trace down from step 2" in r.stderr
    pulses = sorted((read_pulse(out, lab)[0] for lab in list_pulses(out)),
                    key=lambda p: p.extra["trace_step"])
    assert [p.extra["trace_step"] for p in pulses] == [0, 1, 2, 3, 4]
    assert [p.extra["trace_position"] for p in pulses] == [0, -1, -2, -3, -4]
    assert all(np.diff([p.tau_d_ratio for p in pulses]) < 0)
    assert all(np.diff([p.beta for p in pulses]) > 0)
    for lab, p in before.items():
        assert np.array_equal(read_pulse(out, lab)[0].v, p.v)       # not redone
    r = cli_inproc.run([*args, "--max-steps", "4"])
    assert r.returncode == 0 and len(list_pulses(out)) == 5, r.stderr
    r = cli_inproc.run([*args, "--max-steps", "5"])
    assert r.returncode == 0 and "resumed trace down from step 4" in r.stderr, r.stderr
    last = max((read_pulse(out, lab)[0] for lab in list_pulses(out)),
               key=lambda p: p.extra["trace_step"])
    assert last.extra["trace_step"] == 5 and last.tau_d_ratio < pulses[-1].tau_d_ratio
    r = cli_inproc.run([*args, "--max-steps", "6", "--arc-state", "1"])
    assert r.returncode == 2 and "another trace" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and len(list_pulses(out)) == 6
    # a pulse of this trace stripped of its step: refused in one line, the file left as it was
    del last.extra["trace_step"]
    write_pulse(out, last, params)
    r = cli_inproc.run([*args, "--max-steps", "7"])
    assert r.returncode == 2 and "lacks its trace attributes" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and len(list_pulses(out)) == 6


def test_a_trace_its_branch_ended_is_not_retraced(tmp_path, params, pulse12):
    """A trace that stopped for the branch's own reason (here its first step, ds = ds-min = 5,
    fails) stores the reason with its last pulse; the same command again says so and adds
    nothing."""
    src = str(tmp_path / "src.h5")
    write_pulse(src, pulse12.to_pulse(), params)
    out = str(tmp_path / "t.h5")
    args = ["steady", "branch-trace", f"{src}:td1.2000", "--direction", "down", "--ds", "5",
            "--ds-min", "5", "--ds-max", "5", "--out", out, "-q"]
    r = cli_inproc.run(args)
    assert r.returncode == 0, r.stderr
    (lab,) = list_pulses(out)
    assert read_pulse(out, lab)[0].extra["trace_stop_reason"].startswith("step below ds_min")
    r = cli_inproc.run(args)
    assert r.returncode == 0 and "already ended at step 0" in r.stdout, r.stdout
    assert list_pulses(out) == [lab]


def test_another_branch_is_continued_at_its_own_hump_count(tmp_path, params):
    """``steady family --from-pulse`` on the two-hump pulse: the march accepts the steps that keep
    its two humps (the branch it continues, ``Continuation.humps``), where the main family's
    one-hump rule refuses them."""
    from slippulse.steady.branch_search import GUESS_SETS, search
    rep = search(params, 1.2, GUESS_SETS["quick"](), n_points=500, check=False)
    two = [f.pulse for f in rep.found if f.pulse.extra["n_humps"] == 2]
    assert len(two) == 1
    src, out = str(tmp_path / "two.h5"), tmp_path / "up.h5"
    write_pulse(src, two[0], params)
    r = cli_inproc.run(["steady", "family", "--from-pulse", f"{src}:{two[0].label}", "--to",
                        "1.23", "--spacing", "0", "--checks", "inline", "--out", out, "-q"])
    assert r.returncode == 0, r.stderr
    pulses = [read_pulse(str(out), lab)[0] for lab in list_pulses(str(out))]
    assert pulses
    assert all(p.extra["n_humps"] == 2 and p.extra["grid_check_passed"] for p in pulses)
    assert max(p.tau_d_ratio for p in pulses) >= 1.23
    # along the two-hump branch upward β falls (0.00549 at 1.2; the family's 0.00724 there)
    top = max(pulses, key=lambda p: p.tau_d_ratio)
    assert top.beta < two[0].beta < 0.006
    # the rule itself: a two-hump solve is refused where the branch has one hump

    class Solved:                       # judge_pulse reads to_pulse() and stats.message
        stats = SimpleNamespace(message="converged")

        def to_pulse(self):
            return two[0]
    from slippulse.steady.continuation import judge_pulse
    assert judge_pulse(Solved(), 2)[1] and not judge_pulse(Solved())[1]
    assert "2-hump" in judge_pulse(Solved())[2]


def test_cli_real_roots_finds_the_leading_eigenvalue_and_refuses_bad_input(tmp_path, params,
                                                                            pulse12, spectrum12):
    """`steady real-roots`: the root it prints is a sign change of det M on the pulse's grid (to
    its tolerance), the leading eigenvalue of the unpinned spectrum within the pin's rank-one
    change (4e-5 of s at N = 700, measured); bad input: one line, exit 2."""
    from slippulse.spectrum.eigensolve import det_sign
    from slippulse.spectrum.pulse import StabilityOperator
    path = str(tmp_path / "p.h5")
    write_pulse(path, pulse12.to_pulse(), params)
    r = cli_inproc.run(["steady", "real-roots", path, "--between", "15", "30", "--scan", "6"])
    assert r.returncode == 0, r.stderr
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("td1.2000"))
    assert "1 real eigenvalue on [15, 30] c_p/L" in line
    s = float(line.split("c_p/L: ")[1].split(";")[0])
    lead = spectrum12.sigmas[0].real / spectrum12.rate_unit
    assert s == pytest.approx(lead, rel=2e-4)
    op = StabilityOperator(pulse12.to_pulse(), params, pin_translation=True)
    u = op.rate_unit
    assert det_sign(op, (s - 2e-4) * u)[0] != det_sign(op, (s + 2e-4) * u)[0]  # s printed to 6 digits
    for bad, name in ((["--between", "0", "1"], "--between"), (["--between", "2", "1"], "--between"),
                      (["--between", "1", "2", "--scan", "1"], "--scan"),
                      (["--between", "1", "2", "--xtol", "-1"], "--xtol")):
        r = cli_inproc.run(["steady", "real-roots", path] + bad)
        err = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(err) == 1 and name in err[0], r.stderr


def test_null_modes_name_the_trailing_hump_shift_of_the_two_hump_pulse(params):
    """The smallest singular vector of the two-hump pulse's A at 1.2 τ_min moves its trailing hump
    (the humps' separation, cos 0.98 with d ln v/dξ behind the split); the one-hump pulse has no
    split and no trailing shift."""
    from slippulse.steady.branch_search import GUESS_SETS, search
    from slippulse.steady.bifurcation import pulse_null_modes
    from slippulse.steady.null_modes import hump_split
    rep = search(params, 1.2, GUESS_SETS["quick"](), n_points=500, check=False)
    by_humps = {f.pulse.extra["n_humps"]: f.pulse for f in rep.found}
    two, one = by_humps[2], by_humps[1]
    k = hump_split(two.xi, two.v, params.v_star)
    ahead_peak = int(np.argmax(np.where(np.arange(two.n_points) > k, two.v, 0)))
    behind_peak = int(np.argmax(np.where(np.arange(two.n_points) < k, two.v, 0)))
    assert two.v[k] < min(two.v[ahead_peak], two.v[behind_peak])     # a dip between two humps
    m = pulse_null_modes(two, params, 2)
    assert m[0].shape == "trailing-hump shift" and m[0].shift_trailing > 0.95
    assert m[0].sigma < m[1].sigma and m[1].shape != "trailing-hump shift"
    assert hump_split(one.xi, one.v, params.v_star) is None
    assert all(math.isnan(x.shift_trailing) for x in pulse_null_modes(one, params, 2))


def test_the_arc_metric_measures_the_shape_when_asked():
    """z's derivative is the metric's weights (finite differences); with state = 0 ln v does not
    count, with state > 0 its root mean square does; a negative weight is refused."""
    from slippulse.steady.branch_trace import ArcMetric
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.standard_normal(50), [0.3, 1.1]])
    for state in (0.0, 2.0):
        m = ArcMetric(state)
        h = 1e-7
        fd = np.array([(m.z(x + h * e) - m.z(x - h * e))[i] / (2 * h)
                       for i, e in enumerate(np.eye(x.size))])
        assert fd == pytest.approx(m.weights(x), rel=1e-6, abs=1e-9)
    dx = np.zeros(x.size)
    dx[:-2] = 0.5                                  # every node's ln v up by 0.5: RMS 0.5
    assert np.linalg.norm(ArcMetric(0.0).z(x + dx) - ArcMetric(0.0).z(x)) == 0.0
    assert np.linalg.norm(ArcMetric(2.0).z(x + dx) - ArcMetric(2.0).z(x)) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="state"):
        ArcMetric(-1.0)


@pytest.mark.parametrize("state", [0.0, 1.0])
def test_the_check_on_the_normal_hyperplane_agrees_with_fixed_tau_d_on_a_regular_branch(
        params, pulse12, state):
    """On the main family at 1.2 τ_min (regular, far from a fold) the re-solve at 2N − 1 normal to
    the branch moves τ_d by almost nothing and gives the fixed-τ_d check's dβ and dL/L."""
    from slippulse.steady.branch_search import grid_check
    from slippulse.steady.branch_trace import ArcMetric, check_on_normal
    p = pulse12.to_pulse()
    fixed = grid_check(params, p)
    normal = check_on_normal(params, p, ArcMetric(state))
    assert fixed["passed"] and normal["passed"] and normal["n_fine"] == fixed["n_fine"]
    assert abs(normal["dq"]) < 1e-6
    assert normal["dbeta"] == pytest.approx(fixed["dbeta"], abs=1e-7)
    assert normal["dL_rel"] == pytest.approx(fixed["dL_rel"], abs=2e-6)


def test_a_relaid_trace_stays_on_the_branch(params, pulse12):
    """With the grid re-laid after every step (regrid tiny; a point is on the grid before its
    re-lay), each re-lay re-solves the pulse on
    the hyperplane normal to the branch: the trace goes on along the family, and its last point
    is the pulse a fixed-τ_d solve gives on its grid."""
    from slippulse.steady.branch_trace import ArcMetric, TraceSettings, trace
    from slippulse.steady.solver import solve_on_grid
    tr = trace(params, pulse12.to_pulse(), TraceSettings(direction=-1, max_steps=2, regrid=1e-6,
                                                         metric=ArcMetric(1.0)))
    assert [p.grid for p in tr.points] == [0, 0, 1] and all(np.diff([p.q for p in tr.points]) < 0)
    last = tr.pulses[-1]
    prob, x, st = solve_on_grid(params, last.tau_d_ratio, last.xi, np.log(last.v), 1.05 * last.beta)
    assert st.converged and x[-1] == pytest.approx(last.beta, rel=1e-9)


def test_a_trace_relays_its_start_on_the_normal_hyperplane(params, pulse12):
    """``relay_start`` re-solves the start pulse on a grid adapted to it with ``n_points`` nodes,
    on the hyperplane normal to its branch: the first point lies on the new grid, at the start's
    τ_d and β to the change of grid (the branch is not near a fold here), and the trace goes on
    down the family."""
    from slippulse.steady.branch_trace import ArcMetric, TraceSettings, trace
    tr = trace(params, pulse12.to_pulse(), TraceSettings(direction=-1, max_steps=1, n_points=900,
                                                         relay_start=True,
                                                         metric=ArcMetric(1.0)))
    first = tr.points[0]
    assert first.n_points == 900 and tr.pulses[0].n_points == 900
    assert first.q == pytest.approx(1.2, abs=1e-5)
    assert first.beta == pytest.approx(pulse12.to_pulse().beta, rel=1e-3)
    assert len(tr.points) == 2 and tr.points[1].q < first.q


JUMP_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data",
                         "two_hump_fold_jump.h5")


def _jump_pulses():
    """Three pulses of the unguarded march down the two-hump branch toward its first fold
    (1.01867 τ_min), on one deformed grid (N = 2006, the same pin): td1.0199, td1.019381 (where the
    march landed on the fold's far side) and td1.018846 (back on the near side)."""
    from slippulse.steady.bifurcation import pulse_solution
    out = []
    for lab in ("td1.0199", "td1.019381", "td1.018846"):
        p, prm = read_pulse(JUMP_FILE, lab)
        out.append(pulse_solution(p, prm))
    return out, prm


def test_the_sign_guard_sees_the_march_that_jumped_past_a_fold():
    """sign det [J; c] (c a direction along the march, here the first pulse's tangent in (β, q))
    is what the guard compares: the same from td1.0199 to td1.018846 (one side of the fold),
    another at td1.019381, the pulse between them that an unguarded march reached (β 2e-3 above
    its neighbours' line, on the far side). Read off the LU of a nearby matrix where refinement
    on it converges: there it is the dense sign, and where the signs differ it cannot converge."""
    import scipy.linalg
    from slippulse.steady.continuation.arclength import (bordered_sign, family_tangent,
                                                         refined_solution, tangent_matrix)
    (a, jumped, b), _ = _jump_pulses()
    kappa = 0.05
    n_a = family_tangent(a.problem, a.x, (1.0, 0.0, kappa))          # toward larger β
    orient = (n_a[-2], n_a[-1], kappa)
    A = {k: tangent_matrix(p.problem, p.x, orient) for k, p in
         (("a", a), ("jumped", jumped), ("b", b))}
    s = {k: bordered_sign(M) for k, M in A.items()}
    assert s["a"] == s["b"] != s["jumped"]
    assert n_a[-1] < 0                                   # τ_d still falling: the fold lies ahead
    lu_a = scipy.linalg.lu_factor(A["a"])
    near = A["a"].copy()
    near[:-1] *= 1.0 + 1e-6                              # a nearby matrix of the same sign
    assert refined_solution(near, lu_a) is not None and bordered_sign(near, lu_a) == s["a"]
    assert refined_solution(A["jumped"], lu_a) is None
    assert bordered_sign(A["jumped"], lu_a) == s["jumped"]


def test_a_guarded_march_passes_steps_on_its_branch_and_refuses_a_bad_guard():
    """BRANCH (the march of another branch) carries the guard: from td1.0199, two steps toward
    the fold are taken with no refusal and no sign change, τ_d falling and β rising. Its verdict:
    keep a step with no sign to compare or the same sign, retake a changed one while ds/2 is at
    least the floor (0.002), take a change below it as a branch point crossed. A guard whose
    floor is below ds_min, or on natural steps, is refused when built."""
    from slippulse.steady.continuation import (BRANCH, NATURAL, Continuation, SignGuard,
                                               StrategyError)
    (a, _, _), prm = _jump_pulses()
    assert "sign-guard(floor=0.002)" in str(BRANCH)
    m = Continuation(prm, a, BRANCH, stop=1.0)
    for _ in range(2):
        assert m.advance() is None
    assert m.n_failed == 0 and m.sign_changes == []
    assert m.state_attrs()["march_sign_changes"] == 0
    assert m.q < a.x[-1] and m.beta > a.x[-2]
    g = BRANCH.guard
    assert [g.judge(None, -1, 0.1), g.judge(1, 1, 0.1), g.judge(1, -1, 0.1),
            g.judge(1, -1, 0.004), g.judge(1, -1, 0.0039)] == [
        "keep", "keep", "retake", "retake", "branch point"]
    with pytest.raises(StrategyError, match="ds_min"):
        BRANCH.replace(guard=SignGuard(floor=1e-4))
    with pytest.raises(StrategyError, match="arclength"):
        NATURAL.replace(guard=SignGuard())
