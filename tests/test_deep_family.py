"""The product's family: ``slippulse steady family`` — every pulse grid-checked, the deep march as
an object (:class:`Continuation` over a :class:`Strategy`), labels at non-round τ_d, every option
either changing the run or refused with one line and no file touched, kill -9 and resume."""
import dataclasses
import hashlib
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from slippulse.core.h5io import label_ratio, list_pulses, pulse_label, read_pulse, write_pulse
from slippulse.steady.continuation import (AUTO, GRID_TOLERANCE, NEWTON_TOL, AdaptGrid,
                                           Continuation, FreeSteps, GridTolerance, HeldSteps,
                                           LengthPredictor, NestedCheck, NewtonCorrector,
                                           SecantPredictor,
                                           Strategy, StrategyError, StretchGrid,
                                           TangentPredictor, FamilyRun, run_family)
from slippulse.steady.newton import DirectLU, KrylovLU


def _strategy(ds=0.1, ds_max=0.4, ds_min=0.004, max_iter=15, stretch=False, predictor="tangent",
              reuse_lu=True, corrector=None, **held):
    """A strategy of the tests: free steps (held ones with ``held`` given), adapted or stretched
    grid without relay or recentring."""
    pred = {"tangent": TangentPredictor(), "length": LengthPredictor(),
            "secant": SecantPredictor()}[predictor]
    if "predictor_ds_max" in held:
        pred = type(pred)(ds_max=held.pop("predictor_ds_max"))
    corr = corrector or NewtonCorrector(max_iter=max_iter, reuse_lu=reuse_lu)
    steps = (HeldSteps(ds=ds, ds_max=ds_max, ds_min=ds_min, **held) if held else
             FreeSteps(ds=ds, ds_max=ds_max, ds_min=ds_min))
    grid = StretchGrid(relay=0, recentre=0.0) if stretch else AdaptGrid()
    return Strategy(pred, corr, steps, grid)


def _digest(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def test_labels_readable_and_unique_off_round_tau_d():
    assert pulse_label(1.2) == "td1.2000" and pulse_label(1.0125) == "td1.0125"
    assert pulse_label(1.2000000701) == "td1.2000"          # a refined pulse 1e-7 off its target
    assert pulse_label(1.0090741) == "td1.009074"
    assert pulse_label(1.0104033) == "td1.010403" != pulse_label(1.0104012)
    assert label_ratio("td1.2000") == 1.2 and label_ratio("td1.009074") == 1.009074
    assert all(math.isnan(label_ratio(x)) for x in ("td", "x1.2", "tdnan", "td1.2.3", None))
    # the deep steps of docs/analysis.md, 4 decimals collided (1.0092921, 1.0092098 → td1.0092 ...)
    qs = [1.0122681, 1.0119271, 1.0114321, 1.0109587, 1.0105093, 1.0102100, 1.0100086, 1.0098140,
          1.0096264, 1.0094995, 1.0093762, 1.0092921, 1.0092098, 1.0091293, 1.0090741]
    labels = [pulse_label(q) for q in qs]
    assert len(set(labels)) == len(qs)
    assert all(abs(label_ratio(lab) - q) <= 5.0001e-7 for lab, q in zip(labels, qs))


def test_close_deep_pulses_get_longer_labels_and_read_back_under_them(tmp_path, params):
    """A pulse 1.5e-7 in τ_d below the one it came from (ds = 2e-4 at 4.17 km) had the
    same six-decimal label and was not written. It now gets the fewest extra decimals that keep
    it apart; reading it back keeps that label, so every reader finds it under its name."""
    from slippulse.core.h5io import unique_label
    taken = {"td1.008572": 1.0085716}
    assert unique_label(1.0085716, taken) == "td1.008572"          # the same pulse: rewritten
    assert unique_label(1.0085716 + 5e-10, taken) == "td1.008572"
    assert unique_label(1.00857152, taken) == "td1.0085715"        # 8e-8 below: 7 decimals
    taken["td1.0085715"] = 1.00857152
    assert unique_label(1.008571524, taken) == "td1.00857152"      # and 4e-9 off that: 8
    assert unique_label(1.0085, {"td1.0085": 1.00850003}) == "td1.0085000"
    with pytest.raises(ValueError):
        unique_label(1.0, {f"td{1.0:.{d}f}": 1.0 + 2e-9 for d in (4, 6, 7, 8, 9, 10)})
    # the round trip through the file
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=300).to_pulse()
    out = str(tmp_path / "f.h5")
    write_pulse(out, a, params)
    b = solve_pulse(params, 1.2 - 2e-7, n_points=300).to_pulse()
    assert b.label == a.label == "td1.2000"
    b.name = unique_label(b.tau_d_ratio, {a.label: a.tau_d_ratio})
    assert b.label == "td1.1999998"
    write_pulse(out, b, params)
    assert list_pulses(out) == ["td1.2000", "td1.1999998"]
    rb = read_pulse(out, "td1.1999998")[0]
    assert rb.label == "td1.1999998" and rb.tau_d_ratio == b.tau_d_ratio
    assert read_pulse(out, "td1.2000")[0].tau_d_ratio == a.tau_d_ratio     # not overwritten
    # a name that no longer names the pulse's τ_d (a copy re-solved elsewhere) is ignored
    import dataclasses
    assert dataclasses.replace(rb, tau_d_ratio=1.1).label == "td1.1000"


def test_grid_tolerance_is_the_one_place():
    assert GRID_TOLERANCE == GridTolerance(beta=1e-5, L=1e-4)
    assert AUTO.corrector.tol == AUTO.steps.corrector.tol == NEWTON_TOL == 1e-13
    assert GRID_TOLERANCE.passes(9e-6, -9e-5) and not GRID_TOLERANCE.passes(2e-5, 0.0)
    assert not GRID_TOLERANCE.passes(0.0, math.inf) and not GRID_TOLERANCE.passes(math.nan, 0.0)
    with pytest.raises(Exception):
        GRID_TOLERANCE.beta = 1.0                          # frozen


def test_deep_march_object_status_and_counters(params):
    """Continuation: step() advances by one accepted pulse; status "finished" at stop, "stopped" at
    max_length; counters add up; stepping a finished march is an error."""
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    seen = []
    m = Continuation(params, (a.xi, a.x[:-1], a.beta, 1.2),
                     _strategy(ds=DS, ds_max=DS, ds_min=0.25 * DS, max_iter=20, stretch=True),
                     stop=1.195, on_attempt=lambda r, p, msg: seen.append(p is not None))
    assert m.status == "running" and m.n_steps == 0 and m.q == 1.2
    qs = [m.q]
    m_prev_beta = m.beta
    while m.status == "running":
        m_prev_beta = m.beta
        assert m.step() is None
        qs.append(m.q)
        assert m.sol.problem.free == "both" and m.sol.xi.size == 500
    assert m.status == "finished" and m.q <= 1.195 and np.all(np.diff(qs) < 0)
    assert m.n_steps == len(qs) - 1 and m.n_attempts == len(seen) == m.n_steps + m.n_failed
    assert m.n_iterations > 0 and m.fold is None and m.tangent[1] < 0
    with pytest.raises(RuntimeError):
        m.step()
    # a resumed march goes on at the pace of the last step, measured in its own plane
    mr = Continuation(params, m.sol, _strategy(ds=0.1, ds_max=0.4, ds_min=1e-5))
    ds = mr.resume_step(m_prev_beta, qs[-2])
    assert ds == pytest.approx(math.hypot(math.log((1 - m.beta) / (1 - m_prev_beta)),
                                          (m.q - qs[-2]) / mr.kappa), rel=1e-12)
    assert 1e-5 < ds < 0.1 and mr.ds == ds
    assert mr.resume_step(m.beta, m.q) == ds            # no step: ds left as it was
    tight = Continuation(params, m.sol, _strategy(ds=0.1, ds_max=0.4, ds_min=0.05))
    assert tight.resume_step(m_prev_beta, qs[-2]) == 0.05          # clipped to ds_min
    m2 = Continuation(params, m.sol, _strategy(ds=0.004, ds_max=0.004, max_iter=20, stretch=True),
                      max_length=m.L * 1.001)
    m2.step()
    assert m2.status == "stopped" and m2.L >= m.L * 1.001 and "max_length" in m2.message
    # a march that cannot converge fails with the reason
    m3 = Continuation(params, m.sol, _strategy(ds=0.4, ds_min=0.15, max_iter=1))
    assert m3.step() is not None and m3.status == "failed" and "ds fell below" in m3.message
    assert m3.n_failed == m3.n_attempts == 2


def _cli(args):
    return subprocess.run([sys.executable, "-m", "slippulse.cli", "steady", "family", *args],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("args, words", [
    (["--from", "1.1", "--to", "1.2"], "to=1.2 is invalid"),
    (["--from", "1.2", "--to", "1.0"], "tau_d"),
    (["--from", "1.2", "--to", "0.99"], "tau_d"),
    (["--to", "1.009", "--max-points", "3000"], "max-points=3000 is invalid"),
    (["--to", "1.009", "--max-length", "0"], "max-length=0"),
])
def test_family_bad_input_one_line_no_file(tmp_path, capsys, args, words):
    from slippulse import cli
    out = str(tmp_path / "f.h5")
    assert cli.main(["steady", "family", *args, "--out", out, "-q"]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in err
    assert not os.path.exists(out)


def test_family_refuses_file_of_other_parameters_or_older_format(params, tmp_path):
    """A family file of other parameters, or of the older format (pulses without grid checks, as
    the command wrote before every pulse was grid-checked), is refused with one line and left as it was."""
    from dataclasses import replace

    from slippulse import cli
    from slippulse.steady.solver import solve_pulse
    pulse = solve_pulse(params, 1.2, n_points=300).to_pulse()
    old = str(tmp_path / "old.h5")
    write_pulse(old, pulse, params)
    before = _digest(old)
    r = _cli(["--to", "1.19", "--out", old, "-q"])          # as a user runs it: one line, rc 2
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "older format" in r.stderr and _digest(old) == before
    other = str(tmp_path / "other.h5")
    pulse.extra.update({"grid_check_passed": True, "grid_check_tol_beta": 1e-5,
                        "grid_check_tol_L": 1e-4})
    write_pulse(other, pulse, replace(params, D=2 * params.D))
    before = _digest(other)
    assert cli.main(["steady", "family", "--to", "1.19", "--out", other, "-q"]) == 2
    assert _digest(other) == before


@pytest.mark.slow
def test_auto_family_goes_deep_checks_every_pulse_and_stops_at_max_length(params, tmp_path,
                                                                          monkeypatch):
    """The family with the switch moved to the first pulse (DEEP_BETA = 0): the natural pulse and
    the deep march's pulses are all written with their grid check (passed, within the tolerance,
    continuation named), at 6-decimal labels off round τ_d; max_length ends it cleanly."""
    import slippulse.steady.continuation.family as fam
    monkeypatch.setattr(fam, "DEEP_BETA", 0.0)
    tol = GridTolerance(1e-5, 3e-4)
    out = str(tmp_path / "deep.h5")
    rep = run_family(params, out, FamilyRun(start=1.2, stop=1.15, step=0.01, n_points=500,
                                            deep_points=500, n_max=4000, tolerance=tol,
                                            max_length=1.3))
    assert rep.limit_reached and not rep.stopped_early and rep.deep_steps >= 1
    labels = list_pulses(out)
    assert labels[0] == "td1.2000" and len(labels) >= 2
    for lab in labels:
        p, _ = read_pulse(out, lab)
        assert p.converged and p.extra["grid_check_passed"]
        assert abs(p.extra["grid_check_dbeta"]) <= tol.beta
        assert abs(p.extra["grid_check_dL_rel"]) <= tol.L
        assert p.extra["grid_check_n_fine"] == 2 * p.n_points - 1
    deep = [read_pulse(out, lab)[0] for lab in labels[1:]]
    assert all(p.extra["continuation"] == "arclength" and len(p.label) == 10 for p in deep)
    assert deep[-1].L >= 1.3
    # a rerun resumes the deep march from the deepest pulse, on its own grid
    rep2 = run_family(params, out, FamilyRun(start=1.2, stop=1.15, step=0.01, n_points=500,
                                             deep_points=500, n_max=4000, tolerance=tol,
                                             max_length=1.4))
    assert rep2.resumed_from == labels[-1] and rep2.resumed_method == "arclength"
    assert rep2.deep_steps >= 1 and rep2.written and not rep2.stopped_early
    assert all(read_pulse(out, lab)[0].tau_d_ratio < deep[-1].tau_d_ratio for lab in rep2.written)


@pytest.mark.slow
@pytest.mark.parametrize("checks", ["beside", "inline"])
def test_family_kill9_then_rerun_resumes_with_file_intact(tmp_path, checks):
    """kill -9 in the middle of the family command (checks beside the march, the default, or
    inline); the file stays readable, every pulse in it grid-checked; the same command again
    resumes (does not redo the pulses) and finishes."""
    out = str(tmp_path / "f.h5")
    args = ["--from", "1.2", "--to", "1.185", "--points", "1000", "--out", out, "-q",
            "--checks", checks]
    proc = subprocess.Popen([sys.executable, "-m", "slippulse.cli", "steady", "family", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    t0 = time.time()
    while time.time() - t0 < 600:
        if os.path.exists(out) and len(list_pulses(out)) >= 2:
            break
        time.sleep(0.2)
    time.sleep(1.0)                                         # inside the next solve or write
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    first = list_pulses(out)
    assert first[:2] == ["td1.2000", "td1.1950"]
    kept = {lab: read_pulse(out, lab)[0] for lab in first}
    assert all(p.extra["grid_check_passed"] for p in kept.values())
    r = _cli(args)
    assert r.returncode == 0, r.stderr
    assert "resumed from" in r.stderr
    labels = list_pulses(out)
    assert labels == ["td1.2000", "td1.1950", "td1.1900", "td1.1850"]
    for lab, p in kept.items():
        assert np.array_equal(read_pulse(out, lab)[0].v, p.v)   # not redone
    assert all(read_pulse(out, lab)[0].extra["grid_check_passed"] for lab in labels)


#: Every option of ``steady family``: arguments that change the run (compared through
#: ``family_run_args``, the keyword arguments the command passes to ``run_family``), or that
#: change where it goes or what it shows. A new option without an entry here fails the test.
FAMILY_OPTIONS = {
    "--from": ["1.19"], "--to": ["1.009"], "--step": ["0.0025"], "--points": ["1500"],
    "--max-points": ["9000"], "--ds-min": ["0.0005"], "--spacing": ["0.0"],
    "--max-length": ["5000"], "--from-pulse": ["{pulse}"], "--checks": ["{other_checks}"],
}
NOT_THE_RUN = {"-h", "--help", "--out", "-q", "--quiet", "--params", "--set"}


def _family_parser():
    from slippulse.cli.app import build_parser
    sub = build_parser()._subparsers._group_actions[0].choices["steady"]
    return sub._subparsers._group_actions[0].choices["family"]


def test_every_family_option_changes_the_run_or_is_refused(tmp_path, params, pulse12):
    """Each option of ``steady family`` changes the keyword arguments of ``run_family`` (the
    strategy included: ``--ds-min`` is the deep march's smallest step), and each refuses a bad
    value with a one-line ParameterError naming it; the options of other runs' modes are gone and
    refused by the parser. --out, -q, --params and --set are checked by their own tests."""
    import argparse

    from slippulse.cli.steady import family_run_args
    from slippulse.core.params import ParameterError
    import tests.cli_inproc as inproc
    parser = _family_parser()
    names = {o for a in parser._actions for o in a.option_strings}
    assert names - NOT_THE_RUN == set(FAMILY_OPTIONS), "an option of steady family is untested"
    base_args = parser.parse_args([])
    base = family_run_args(base_args, params)
    assert base["strategy"] == AUTO and base["spacing"] == 0.01
    stored = str(tmp_path / "stored.h5")
    write_pulse(stored, pulse12.to_pulse(), params)
    pulse = f"{stored}:td1.2000"
    for opt, (val,) in FAMILY_OPTIONS.items():
        other = "inline" if base["checks"] == "beside" else "beside"
        got = family_run_args(parser.parse_args([opt, val.format(pulse=pulse,
                                                                 other_checks=other)]), params)
        changed = {k for k in base if got[k] != base[k]}
        assert changed, f"{opt} {val} changes nothing"
        if opt == "--ds-min":
            assert changed == {"strategy"} and got["strategy"].steps.ds_min == 0.0005
            assert got["strategy"].replace(steps=AUTO.steps) == AUTO   # nothing else of it
        if opt == "--from-pulse":
            assert got["origin"].label == "td1.2000" and got["start"] == got["origin"].tau_d_ratio
    bad = {"--step": "0", "--points": "10", "--max-points": "100", "--ds-min": "0.004",
           "--spacing": "0.9", "--max-length": "0", "--from": "2", "--to": "0.5",
           "--from-pulse": str(tmp_path / "none.h5:td1.2000"), "--checks": "aside"}
    assert set(bad) == set(FAMILY_OPTIONS)
    for opt, val in bad.items():
        with pytest.raises(ParameterError, match=opt.lstrip("-").split("-")[0]):
            family_run_args(parser.parse_args([opt, val]), params)
        r = inproc.run(["steady", "family", opt, val, "--out", str(tmp_path / "x.h5"), "-q"])
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
        assert not os.path.exists(tmp_path / "x.h5")
    for gone in (["--deep", "beta"], ["--no-grid-check"]):
        r = inproc.run(["steady", "family", *gone, "--out", str(tmp_path / "x.h5"), "-q"])
        assert r.returncode == 2 and "unrecognized" in r.stderr
    assert isinstance(parser, argparse.ArgumentParser)


def test_a_strategy_is_a_value_refused_when_it_cannot_work():
    """A combination prints its parts with their parameters, compares by value, and refuses what
    cannot work when built: held steps without the length/secant predictor or without a
    stretched grid, the length predictor on an adapted grid, recentring without held steps, bad
    parameters of a part."""
    text = str(AUTO)
    for word in ("secant(ds_max=0.002)", "newton(max_iter=25", "held(", "line_search=natural",
                 "stretch(", "recentre=0.001",
                 "nested(linear=krylov(precision=single"):
        assert word in text
    assert AUTO == Strategy(SecantPredictor(), NewtonCorrector(), HeldSteps(), StretchGrid())
    assert AUTO.replace(check=NestedCheck(DirectLU("single"))) != AUTO
    with pytest.raises(StrategyError, match="linear='half'"):
        NestedCheck(linear="half")
    with pytest.raises(ValueError, match="precision='half'"):
        KrylovLU("half")
    with pytest.raises(StrategyError, match="check="):
        AUTO.replace(check="nested")
    assert AUTO.replace(grid=StretchGrid(relay=0)) != AUTO
    with pytest.raises(StrategyError, match="held"):
        Strategy(TangentPredictor(), NewtonCorrector(), HeldSteps(), StretchGrid())
    with pytest.raises(StrategyError, match="StretchGrid"):
        Strategy(SecantPredictor(), NewtonCorrector(), HeldSteps(), AdaptGrid())
    with pytest.raises(StrategyError, match="stretched grid"):
        Strategy(LengthPredictor(), NewtonCorrector(), FreeSteps(), AdaptGrid())
    with pytest.raises(StrategyError, match="ds_min"):
        AUTO.replace(steps=HeldSteps(ds_min=0.004))
    Strategy(SecantPredictor(), NewtonCorrector(), FreeSteps(), StretchGrid())
    for bad in (lambda: NewtonCorrector(line_search="armijo"), lambda: NewtonCorrector(max_iter=0),
                lambda: FreeSteps(ds=0.001, ds_min=0.01), lambda: HeldSteps(cap_shrink=0.0),
                lambda: LengthPredictor(ds_max=0.0), lambda: StretchGrid(front_zone=2.0),
                lambda: Strategy(predictor="secant")):
        with pytest.raises(StrategyError):
            bad()


def test_a_resumed_deep_march_starts_from_the_step_before_it(tmp_path, pulse12, params):
    """`_previous_arclength`: the deepest converged arclength pulse above the one the march
    resumes from (its (β, q) set the first step); None without one.
    `_resume` puts it on the report."""
    import dataclasses
    from slippulse.core.h5io import write_pulse
    from slippulse.steady.continuation.family import _previous_arclength, _resume
    from slippulse.steady.continuation.report import FamilyReport
    out = str(tmp_path / "fam.h5")
    assert _previous_arclength([], 1.0) is None                   # no pulses
    base = pulse12.to_pulse()
    for q, b, method, ok in [(1.2, 0.01, "tau_d", True), (1.19, 0.02, "arclength", True),
                             (1.18, 0.03, "arclength", True), (1.175, 0.035, "arclength", False),
                             (1.17, 0.04, "arclength", True)]:
        write_pulse(out, dataclasses.replace(base, tau_d_ratio=q, tau_d=q * base.tau_min, beta=b,
                                             converged=ok, extra={"continuation": method}), params)
    pulses = [read_pulse(out, lab)[0] for lab in list_pulses(out)]
    assert _previous_arclength(pulses, 1.17) == (0.03, 1.18, base.L)  # not the unconverged 1.175
    assert _previous_arclength(pulses, 1.19) is None              # above it: a tau_d pulse only
    rep = FamilyReport()
    assert _resume(params, out, rep).q == 1.17
    assert rep.resumed_previous == (0.03, 1.18, base.L) and rep.resumed_method == "arclength"
    assert rep.resumed_held is False and math.isnan(rep.resumed_cap)   # written without them
    write_pulse(out, dataclasses.replace(base, tau_d_ratio=1.165, tau_d=1.165 * base.tau_min,
                                         beta=0.045, extra={
        "continuation": "arclength", "march_held": True, "march_cap": 0.0016}), params)
    rep = FamilyReport()
    assert _resume(params, out, rep).q == 1.165 and rep.resumed_held is True
    assert rep.resumed_cap == 0.0016


def test_a_resumed_march_starts_held_if_its_pulse_was_written_held(params, pulse12):
    """Every pulse a march with held steps hands over carries ``march_held`` and ``march_cap``
    (:meth:`Continuation.state_attrs`, with the strategy printed); a march resumed from a held
    pulse (:meth:`Continuation.hold`) starts held at that cap, the first ds within it, instead of
    learning it again from a failed tangent step; a strategy without held steps ignores it."""
    from slippulse.steady.continuation.gridcheck import as_both
    start = as_both(params, pulse12)
    m = Continuation(params, start, AUTO)
    attrs = m.state_attrs()
    assert attrs["march_held"] is False and attrs["march_cap"] == 0.002
    assert attrs["continuation_strategy"] == str(AUTO) and attrs["continuation"] == "arclength"
    m.hold(0.0013)
    assert m.held and (m.cap, m.ds) == (0.0013, 0.0013)
    assert m.state_attrs()["march_held"] is True and m.state_attrs()["march_cap"] == 0.0013
    free = Continuation(params, start, _strategy(stretch=True, predictor="secant"))
    free.hold(0.0013)
    assert not free.held and free.ds == 0.1


class _GrowingMarch(Continuation):
    """A Continuation whose accepted step (``advance``) only lengthens the pulse by 0.3 %."""

    def advance(self):
        self.L *= 1.003
        self.n_steps += 1
        self._update_status()
        return None


class _ShrinkingMarch(Continuation):
    """A Continuation whose accepted step shortens the pulse by 0.3 %, finished after 40 steps
    (a branch followed toward shorter pulses, e.g. a two-hump branch upward in τ_d)."""

    def advance(self):
        self.L /= 1.003
        self.n_steps += 1
        if self.n_steps >= 40:
            self.status, self.message = "finished", "40 steps"
        return None


def _handed_lengths(params, pulse12, march, **kw):
    """Run ``march`` (a Continuation class) from the 1.2 pulse on a deformed grid with free
    steps; returns (the march, its start's L, the L of each pulse handed to ``on_accept``)."""
    from slippulse.steady.continuation import Accepted
    from slippulse.steady.continuation.gridcheck import as_both
    written = []

    def on_accept(sol, extra):
        written.append(m.L)
        return Accepted(True, sol)

    start = as_both(params, pulse12)
    m = march(params, start, AUTO.replace(grid=StretchGrid(recentre=0.0), steps=FreeSteps()),
              on_accept=on_accept, **kw)
    m.run()
    return m, start.to_pulse().L, written


@pytest.mark.parametrize("spacing", [0.0, 0.01])
def test_the_deep_march_hands_over_a_pulse_per_spacing_of_L_and_its_last(params, pulse12,
                                                                          spacing):
    """``spacing`` (`--spacing`): a step is handed to ``on_accept`` (checked and written) once L
    has grown by the spacing since the last one, and the march's last pulse always is; spacing 0
    hands over every step."""
    from slippulse.steady.continuation.gridcheck import as_both
    L0 = as_both(params, pulse12).to_pulse().L
    m, _, written = _handed_lengths(params, pulse12, _GrowingMarch, max_length=1.1 * L0,
                                    spacing=spacing)
    assert m.status == "stopped"
    assert written[-1] >= 1.1 * L0 and m.n_written == len(written)
    if spacing == 0:
        assert len(written) == m.n_steps
    else:
        grown = np.array(written[:-1]) / np.array([L0] + written[:-2])
        assert grown.size >= 2 and np.all(grown >= 1 + spacing)
        assert len(written) < m.n_steps / 3


@pytest.mark.parametrize("spacing", [0.0, 0.01])
def test_a_march_toward_shorter_pulses_hands_over_a_pulse_per_spacing_too(params, pulse12,
                                                                          spacing):
    """The spacing is a change of L either way, |ln(L/L_last)| ≥ ln(1 + spacing): a march along
    which L falls writes (and checks) its pulses as one along which it grows, not only its last."""
    m, L0, written = _handed_lengths(params, pulse12, _ShrinkingMarch, spacing=spacing)
    assert m.status == "finished"
    if spacing == 0:
        assert len(written) == m.n_steps == 40
    else:
        shrunk = np.array([L0] + written[:-2]) / np.array(written[:-1])
        assert shrunk.size >= 8 and np.all(shrunk >= 1 + spacing)
        assert written[-1] == pytest.approx(L0 / 1.003 ** 40)


class _StallingCorrector(NewtonCorrector):
    """Newton that fails (a mocked stall) on grids of ``n`` nodes and is the real one on others."""

    def solve(self, problem, x0, lu=None, creep=None):
        if problem.base.n == STALL_N[0]:
            STALL_N[1] += 1
            from slippulse.steady.newton import SolveStats
            return x0, SolveStats(False, "mocked: not converged after 25 iterations", 25, 1.0)
        STALL_N[2] += 1
        return super().solve(problem, x0, lu=lu, creep=creep)


STALL_N = [0, 0, 0]          # the stalling grid's N, stalled attempts, real attempts


@pytest.mark.parametrize("case", ["passes", "check fails", "re-solve fails", "off"])
def test_the_deep_march_refines_the_healing_front_where_the_corrector_stalls(
        monkeypatch, tmp_path, params, pulse12, case):
    """Where the corrector fails at ds_min (a stalling corrector), the march re-solves its pulse
    with the healing front's cells split (``StretchGrid.relay``), hands it over to be checked and
    written like every deep pulse, and goes on from it; a refined pulse that fails its check is
    written failed and ends the march, as does a re-solve that does not converge (nothing
    written); relay=0: the march ends at the stall."""
    from slippulse.steady.continuation import driver
    from slippulse.steady.continuation.gridcheck import as_both
    start = as_both(params, pulse12)
    STALL_N[:] = [start.xi.size, 0, 0]
    if case == "re-solve fails":
        monkeypatch.setattr(driver, "refine_front", lambda *a, **k: (
            None, math.inf, math.inf, "healing front refined: the re-solve did not "
                                      "converge (mocked)"))
    out = str(tmp_path / "fam.h5")
    tol = GridTolerance(1e-30, 1e-30) if case == "check fails" else GRID_TOLERANCE
    strategy = AUTO.replace(corrector=_StallingCorrector(),
                            steps=FreeSteps(ds=0.008, ds_min=0.004),
                            grid=StretchGrid(relay=0 if case == "off" else 3, recentre=0.0))
    L0 = start.to_pulse().L
    run = FamilyRun(stop=1.001, strategy=strategy, tolerance=tol, n_max=2 * 700 - 1,
                    deep_points=700, max_length=L0 * 1.004, spacing=0.0)
    rep = run_family(params, out, run, origin=pulse12.to_pulse())
    labels = list_pulses(out) if os.path.exists(out) else []
    pulses = [read_pulse(out, lab)[0] for lab in labels]
    # the stall: ds halved from 0.008 below 0.004, two failed attempts on the start's grid
    assert STALL_N[1] == 2
    if case == "off":
        assert rep.stopped_early and "ds fell below" in rep.stop_reason and not labels
        assert STALL_N[2] == 0
        return
    if case == "re-solve fails":
        assert rep.stopped_early and "did not converge (mocked)" in rep.stop_reason
        assert not labels and STALL_N[2] == 0
        return
    relaid = [p for p in pulses if p.extra.get("relaid")]
    assert len(relaid) == 1
    r = relaid[0]
    # re-solved on the start's grid with the healing front's cells split (nested), then checked
    assert "grid_check_passed" in r.extra and r.extra["continuation"] == "arclength"
    assert r.extra["continuation_strategy"] == str(strategy)
    assert r.xi.size > 700 and np.isin(start.xi, r.xi).all()
    assert abs(r.tau_d_ratio - 1.2) < 1e-6
    assert math.isfinite(r.extra["relay_dL_rel"]) and math.isfinite(r.extra["relay_dbeta"])
    if case == "check fails":
        assert not r.converged and r.extra["status"] == "failed"
        assert not r.extra["grid_check_passed"] and rep.stopped_early
        assert "failed its grid check" in rep.stop_reason and STALL_N[2] == 0
        assert rep.written == []
        return
    # passed: written as good, and the march went on from it on the new grid to max_length
    assert r.converged and r.extra["grid_check_passed"]
    assert abs(r.extra["grid_check_dL_rel"]) <= GRID_TOLERANCE.L
    assert STALL_N[2] >= 1 and rep.limit_reached and not rep.stopped_early
    assert rep.deep_steps >= 1 and len(rep.written) >= 2
    assert all(p.converged and p.extra["grid_check_passed"] for p in pulses)
    assert max(p.L for p in pulses) >= L0 * 1.004


#: the fixed step of :func:`test_the_secant_predictor_of_the_deep_march` (measured at 1.2 τ_min,
#: N = 500: starting residual "tangent" 0.028, "secant" 0.0024, 4 → 3 iterations; at ds = 0.0003
#: 0.0093 against 0.00024: O(ds) against O(ds²))
DS = 0.001


class _RecordingCorrector(NewtonCorrector):
    """Newton that records max|r| at the predicted point of every attempt."""

    def solve(self, problem, x0, lu=None, creep=None):
        STARTS.append(float(np.max(np.abs(problem.residual(x0)))))
        return super().solve(problem, x0, lu=lu, creep=creep)


STARTS = []


def _predictor_march(params, start, predictor, n, monkeypatch):
    """``n`` steps of the deformed-grid march at the fixed ds = DS from ``start`` with
    ``predictor``: the march, and per step (predictor, max|r| at the predicted point, Newton
    iterations, the shift of the grid's front zone, L before the step). Without reuse of the
    corrector's LU: its chord iterations would take the Newton iterations that measure the
    predictor."""
    from slippulse.steady.continuation import driver
    shifts = []
    real_grid = driver.stretch_grid

    def stretch_grid(xi, x0, shift, *args):
        shifts.append(shift)
        return real_grid(xi, x0, shift, *args)

    monkeypatch.setattr(driver, "stretch_grid", stretch_grid)
    m = Continuation(params, start, _strategy(
        ds=DS, ds_max=DS, ds_min=0.25 * DS, stretch=True, predictor=predictor,
        corrector=_RecordingCorrector(max_iter=20, reuse_lu=False)))
    rows = []
    for _ in range(n):
        L0 = m.L
        assert m.step() is None and m.n_failed == 0
        rows.append((m.last_predictor, STARTS[-1], m.sol.stats.iterations, shifts[-1], L0))
    return m, rows


def test_the_secant_predictor_of_the_deep_march(params, monkeypatch):
    """On the deformed grid the tangent predictor moves the front zone by the tangent's change of
    L, which deep in the family falls short (the healing front lands a cell off its nodes every
    step and the corrector creeps); the length predictor moves it by the last step's change of L
    per ds; the secant one also predicts the nodal ln v along the secant through the last two
    pulses: its starting residual is second order in ds. Same ds, same pulses: length and secant
    deform the grid alike and converge to the same pulse (solver tolerance); tangent deforms it
    otherwise (another discretisation, well within the grid criterion). replace/restart drop the
    nodal secant and keep dL/ds; a new march has neither."""
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    start = (a.xi, a.x[:-1], a.beta, 1.2)
    mt, tan = _predictor_march(params, start, "tangent", 4, monkeypatch)
    ml, length = _predictor_march(params, start, "length", 4, monkeypatch)
    ms, sec = _predictor_march(params, start, "secant", 4, monkeypatch)
    assert [r[0] for r in tan] == ["tangent"] * 4
    assert [r[0] for r in length] == ["tangent"] + ["length"] * 3
    assert [r[0] for r in sec] == ["tangent", "length", "secant", "secant"]
    # the first step is the same in all three
    assert tan[0][1:4] == length[0][1:4] == sec[0][1:4]
    # length: the front zone moved by the last step's change of L per ds
    for k in (1, 2, 3):
        assert length[k][3] == pytest.approx(length[k][4] - length[k - 1][4], rel=1e-12)
        assert sec[k][3] == pytest.approx(sec[k][4] - sec[k - 1][4], rel=1e-12)
    # secant: the starting residual falls by a clear factor, and so do the iterations
    for k in (2, 3):
        assert sec[k][1] < 0.2 * length[k][1] and sec[k][1] < 0.2 * tan[k][1]
        assert sec[k][2] < tan[k][2]
    # the same pulses
    assert np.allclose(ms.sol.xi, ml.sol.xi, rtol=0, atol=1e-9)
    assert np.max(np.abs(ms.sol.x - ml.sol.x)) < 1e-10
    assert abs(ms.q - mt.q) < 1e-8 and abs(ms.L / mt.L - 1.0) < 0.1 * GRID_TOLERANCE.L
    # the history
    ms.replace(ms.sol)
    assert ms.step() is None and ms.last_predictor == "length"
    assert ms.step() is None and ms.last_predictor == "secant"
    ms.restart(ms.sol, DS)
    assert ms.step() is None and ms.last_predictor == "length"
    fresh = Continuation(params, ms.sol, ms.strategy)
    assert fresh.step() is None and fresh.last_predictor == "tangent"
    # a march resumed from a file: dL/ds of the step between the two last pulses seeds "length"
    resumed = Continuation(params, fresh.sol, ms.strategy)
    resumed.resume_step(ms.beta, ms.q, ms.L)
    dist = math.hypot(math.log((1 - fresh.beta) / (1 - ms.beta)), (fresh.q - ms.q) / resumed.kappa)
    assert resumed.step() is None and resumed.last_predictor == "length"
    # with held steps, a resume from two pulses far apart starts at the predictor's ds_max
    far = _strategy(ds=DS, ds_max=DS, ds_min=0.25 * DS, stretch=True, predictor="secant",
                    corrector=NewtonCorrector(max_iter=20, reuse_lu=False),
                    predictor_ds_max=0.5 * dist, cap_shrink=1.0)
    held = Continuation(params, fresh.sol, far)
    assert held.resume_step(ms.beta, ms.q, ms.L) == pytest.approx(max(0.5 * dist, 0.25 * DS))
    assert held.step() is None and held.last_predictor == "length"
    unheld = Continuation(params, fresh.sol, far.replace(steps=FreeSteps(ds=DS, ds_max=DS,
                                                                         ds_min=0.25 * DS)))
    assert unheld.resume_step(ms.beta, ms.q, ms.L) == pytest.approx(
        min(max(dist, 0.25 * DS), DS), rel=1e-12)
    # above the predictor's ds_max the march is the tangent's, history or not
    wide = Continuation(params, ms.sol, ms.strategy.replace(
        steps=FreeSteps(ds=0.004, ds_max=0.004, ds_min=0.001)))
    wide.step()
    assert wide.last_predictor == "tangent"


@pytest.mark.parametrize("case", ["far", "near", "not held", "off", "fails", "another"])
def test_the_march_moves_the_zone_back_onto_the_healing_front(monkeypatch, params, pulse12,
                                                               case):
    """``StretchGrid.recentre``: a march whose zone about the healing front lies more than
    recentre · L off its drop goes on from the re-solved pulse (``relay.recentre``, mocked here;
    tested in test_recentre.py), held or not; not when the offset is within it, not with
    recentre = 0; a re-solve that fails, or that moves L at fixed τ_d by more than
    RESOLVE_CHANGE grid tolerances (another solution), leaves the march on its pulse."""
    from slippulse.steady.continuation.tolerance import GRID_TOLERANCE, RESOLVE_CHANGE
    from slippulse.steady.continuation import driver
    from slippulse.steady.continuation.gridcheck import as_both
    start = as_both(params, pulse12)
    grid = StretchGrid(recentre=0.0) if case == "off" else StretchGrid()
    steps = FreeSteps() if case == "off" else HeldSteps()
    march = Continuation(params, start, AUTO.replace(grid=grid, steps=steps))
    if case != "not held":
        march.hold(0.002)
    L = march.L
    new = as_both(params, pulse12)
    calls = []
    off = 2.0 * 0.001 * L if case != "near" else 0.5 * 0.001 * L
    monkeypatch.setattr(driver, "zone_offset", lambda params, sol, back_zone: (off, -L))

    def fake(params, sol, front_zone, back_zone, offset=None):
        assert offset == (off, -L)                    # the offset measured once, passed on
        calls.append(sol)
        # within the bound (far, not held: just inside it) or past it (another)
        dL = RESOLVE_CHANGE * GRID_TOLERANCE.L * (1.5 if case == "another" else 0.9)
        return (None if case == "fails" else new), 0.0, dL, off, "mocked"

    monkeypatch.setattr(driver, "recentre", fake)
    cur = march.sol
    moved = march.recentre_front()
    goes = case in ("far", "not held")
    assert moved is goes
    assert march.sol is (new if goes else cur)
    assert calls == ([cur] if case in ("far", "not held", "fails", "another") else [])
    assert march.n_recentred == (1 if goes else 0)


def test_a_stored_pulse_continued_both_ways_reproduces_its_neighbours(tmp_path, params):
    """``--from-pulse`` (``run_family(origin=..., strategy=FROM_PULSE)``): a pulse of a quick
    family (1.2 → 1.175 on 500 points, every pulse grid-checked) continued on its own grid by the
    deep march's pseudo-arclength steps, down to 1.18 and up to 1.195: every pulse written is checked, τ_d
    moves monotonically toward --to and the march ends past it, by less than the way there
    (the last step shortened);
    each pulse is the family's: the family's nearest pulse, solved at its τ_d on the family's
    grid, gives its β and L within the grid tolerance (both grid-converged to it)."""
    from slippulse.steady.continuation import FROM_PULSE
    from slippulse.steady.solver import solve_pulse
    fam = str(tmp_path / "fam.h5")
    rep = run_family(params, fam, FamilyRun(start=1.2, stop=1.175, step=0.005, n_points=500))
    assert not rep.stopped_early and len(list_pulses(fam)) == 6
    family = [read_pulse(fam, lab)[0] for lab in list_pulses(fam)]
    start = read_pulse(fam, "td1.1900")[0]
    for to in (1.18, 1.195):
        out = str(tmp_path / f"to{to}.h5")
        r = run_family(params, out, FamilyRun(stop=to, strategy=FROM_PULSE), origin=start)
        assert not r.stopped_early and r.deep_steps >= 1, r.stop_reason
        pulses = [read_pulse(out, lab)[0] for lab in list_pulses(out)]
        assert pulses and all(p.converged and p.extra["grid_check_passed"] for p in pulses)
        assert all(p.extra["continuation"] == "arclength" for p in pulses)
        qs = np.array([start.tau_d_ratio] + [p.tau_d_ratio for p in pulses])
        sign = np.sign(to - start.tau_d_ratio)
        assert np.all(sign * np.diff(qs) > 0) and r.reached == qs[-1]
        assert 0 <= sign * (qs[-1] - to) < abs(to - start.tau_d_ratio)
        for p in pulses:
            ref = min(family, key=lambda f: abs(f.tau_d_ratio - p.tau_d_ratio))
            b = solve_pulse(params, p.tau_d_ratio, n_points=ref.n_points, passes=0,
                            guess=(ref.xi, np.log(ref.v), ref.beta), adapt_guess=False)
            assert b.stats.converged
            got = b.to_pulse()
            assert abs(got.beta - p.beta) <= GRID_TOLERANCE.beta
            assert abs(got.L / p.L - 1.0) <= GRID_TOLERANCE.L


@pytest.mark.parametrize("case, words", [
    ("no file", "no such file"), ("no label", "no pulse label"), ("not FILE:LABEL", "FILE:LABEL"),
    ("other parameters", "other parameters"), ("step given", "--step=0.001 is not used"),
    ("to at the pulse", "own tau_d"), ("out holds pulses", "holds pulses already"),
])
def test_from_pulse_refuses_bad_input_with_one_line_and_no_file(tmp_path, params, pulse12, case,
                                                                 words):
    """``--from-pulse``: a missing file or label, a value that is not FILE:LABEL, a file of
    other parameters, an option of the natural steps, --to at the pulse's own τ_d, an --out that
    already holds pulses: exit 2, one line naming the problem, no file written or changed."""
    from dataclasses import replace

    import tests.cli_inproc as inproc
    stored = str(tmp_path / "stored.h5")
    write_pulse(stored, pulse12.to_pulse(), params)
    arg, extra, out = f"{stored}:td1.2000", ["--to", "1.19"], str(tmp_path / "new.h5")
    if case == "no file":
        arg = str(tmp_path / "none.h5:td1.2000")
    elif case == "no label":
        arg = f"{stored}:td1.1000"
    elif case == "not FILE:LABEL":
        arg = stored
    elif case == "other parameters":
        other = str(tmp_path / "other.h5")
        write_pulse(other, pulse12.to_pulse(), replace(params, D=2 * params.D))
        arg = f"{other}:td1.2000"
    elif case == "step given":
        extra += ["--step", "0.001"]
    elif case == "to at the pulse":
        extra = ["--to", "1.2"]
    elif case == "out holds pulses":
        out = stored
    before = _digest(stored)
    r = inproc.run(["steady", "family", "--from-pulse", arg, *extra, "--out", out, "-q"])
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in r.stderr
    assert _digest(stored) == before
    if out != stored:
        assert not os.path.exists(out)


def test_natural_steps_are_strategies_of_the_one_driver(params, pulse12):
    """The shallow family's steps run in :class:`Continuation` too: τ_d steps onto the targets
    (``NATURAL``: each accepted pulse handed over, status "finished" at the last target), β steps
    past a target and onto it (``BETA_STEPS``: the pulses above it handed over as "beta", the one
    at it as "tau_d"), both counted; at β ≥ beta_cap the march is "capped" before any attempt, and
    past beta_switch the τ_d steps are "stalled". The β route lands on the τ_d route's pulse
    (other grids: within the grid tolerance). A natural predictor with arclength steps, or
    natural steps with another predictor, is refused when built."""
    from slippulse.steady.continuation import (BETA_STEPS, NATURAL, NaturalPredictor,
                                               PulseOnGrid, ShrinkSteps, TargetSteps)
    start = PulseOnGrid.of(pulse12, pulse12.to_pulse().L)
    grid = AdaptGrid(regrid=0.1, n_points=700)
    tau = NATURAL.replace(grid=grid)
    handed = []

    def on_accept(sol, extra):
        handed.append((float(sol.to_pulse().tau_d_ratio), extra["continuation"],
                       extra["continuation_strategy"]))

    m = Continuation(params, start, tau, targets=[1.195, 1.19], on_accept=on_accept)
    assert m.status == "running" and m.last_predictor == "natural"
    assert m.run() == "finished" and m.q == 1.19 and m.targets == []
    assert m.n_steps == len(handed) == 2 and m.n_attempts == m.n_steps + m.n_failed
    assert [h[:2] for h in handed] == [(1.195, "tau_d"), (1.19, "tau_d")]
    assert handed[0][2] == str(tau)
    handed.clear()
    beta_steps = BETA_STEPS.replace(grid=grid, steps=ShrinkSteps(shrink=0.999, min_shrink=0.9995))
    b = Continuation(params, start, beta_steps, targets=[1.19], on_accept=on_accept)
    assert b.run() == "finished" and b.q == 1.19 and b.n_steps == len(handed) >= 2
    assert [h[1] for h in handed] == ["beta"] * (len(handed) - 1) + ["tau_d"]
    assert all(q > 1.19 for q, _, _ in handed[:-1])
    assert abs(b.beta - m.beta) <= GRID_TOLERANCE.beta
    capped = Continuation(params, start, tau, targets=[1.195], beta_cap=0.0)
    assert capped.run() == "capped" and capped.n_attempts == 0
    stalled = Continuation(params, start, tau.replace(steps=TargetSteps(beta_switch=1e-3)),
                           targets=[1.195])
    assert stalled.run() == "stalled" and "beta_switch" in stalled.message
    with pytest.raises(StrategyError, match="TargetSteps"):
        Strategy(NaturalPredictor("tau_d"), NewtonCorrector(), FreeSteps(), AdaptGrid())
    with pytest.raises(StrategyError, match="ShrinkSteps"):
        Strategy(NaturalPredictor("beta"), NewtonCorrector(), TargetSteps(), AdaptGrid())
    with pytest.raises(StrategyError, match="AdaptGrid"):
        Strategy(NaturalPredictor("tau_d"), NewtonCorrector(), TargetSteps(), StretchGrid())
    with pytest.raises(StrategyError, match="NaturalPredictor"):
        Strategy(TangentPredictor(), NewtonCorrector(), ShrinkSteps(), AdaptGrid())
    for bad in (lambda: NaturalPredictor("q"), lambda: TargetSteps(step=0.0),
                lambda: TargetSteps(min_step=0.01), lambda: ShrinkSteps(shrink=0.98),
                lambda: FreeSteps(overshoot=0.0), lambda: AdaptGrid(n_points=1)):
        with pytest.raises(StrategyError):
            bad()


def test_from_pulse_marches_the_deep_family_with_auto_and_another_branch_with_free_steps(
        pulse12):
    """``--from-pulse`` picks its march by the pulse: the deep main family's (one hump,
    β ≥ DEEP_BETA) is AUTO's with its held cap, tuned to that family's scale; any other pulse
    (a two-hump one, or the family above the deep march) gets BRANCH, free steps, where the
    held cap would move β by 2e−4 a step."""
    import dataclasses
    from slippulse.steady.continuation import BRANCH, FROM_PULSE, from_pulse_strategy
    from slippulse.steady.continuation.family import DEEP_BETA
    p = pulse12.to_pulse()
    deep = dataclasses.replace(p, beta=DEEP_BETA + 1e-4, extra=dict(p.extra, n_humps=1))
    two = dataclasses.replace(deep, extra=dict(p.extra, n_humps=2))
    assert from_pulse_strategy(deep) is FROM_PULSE and FROM_PULSE.held
    assert from_pulse_strategy(two) is BRANCH and from_pulse_strategy(p) is BRANCH
    assert not BRANCH.held and BRANCH.steps.overshoot == FROM_PULSE.steps.overshoot


class _FoldingMarch(Continuation):
    """A Continuation whose accepted steps lower τ_d by 0.002 four times, then raise it (a fold),
    L unchanged."""

    def advance(self):
        dq = -0.002 if self.n_steps < 4 else 0.002
        self.q += dq
        self.tangent = (1.0, dq / 0.002)
        if self.direction * self.tangent[1] < 0 and self.fold is None:
            self.fold = self.q - dq
        self.n_steps += 1
        self._update_status()
        if self.status == "running" and self.n_steps >= 20:       # never, once the rule holds
            self.status, self.message = "failed", "20 steps past the fold"
        return None


def test_a_march_whose_branch_folds_before_stop_ends_back_at_its_start_tau_d(params, pulse12):
    """Toward a stop beyond a fold the branch never gets there: the march follows the fold's
    other side back past the start's τ_d and stops there, saying where the branch folded."""
    from slippulse.steady.continuation.gridcheck import as_both
    start = as_both(params, pulse12)
    q0 = float(start.x[-1])
    m = _FoldingMarch(params, start, AUTO.replace(grid=StretchGrid(recentre=0.0),
                                                  steps=FreeSteps()), stop=q0 - 0.05)
    assert m.run() == "stopped"
    assert m.q >= q0 - 1e-12 and m.n_steps == 8
    assert f"folds at tau_d/tau_min={q0 - 0.008:.6f}" in m.message
    # without a fold the stop is reached as before
    m2 = _FoldingMarch(params, start, AUTO.replace(grid=StretchGrid(recentre=0.0),
                                                   steps=FreeSteps()), stop=q0 - 0.005)
    assert m2.run() == "finished" and m2.n_steps == 3
