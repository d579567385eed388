"""The benchmark suite's runner (benchmarks/run.py): its groups, its side-by-side table, and the
refusal of an unknown group. The benchmarks themselves are measurements, not tests."""
import importlib.util
import os
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
BENCH = os.path.join(HERE, os.pardir, "benchmarks")


def _load(name):
    spec = importlib.util.spec_from_file_location(name, os.path.join(BENCH, f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_suite_has_the_nine_groups_each_with_a_benchmark():
    suite = _load("suite")
    assert list(suite.GROUPS) == ["steady", "family", "branch", "deep", "reach", "continuation",
                                  "spectrum", "sbi", "gpu"]
    assert all(suite.GROUPS[g] for g in suite.GROUPS)
    assert all(callable(f) for f in suite.BENCHMARKS.values())


def test_table_puts_base_and_this_tree_side_by_side_and_shows_a_base_error():
    run = _load("run")
    med = run.median_figures([{"wall s": 3.0, "kind": "a"}, {"wall s": 1.0, "kind": "a"},
                              {"wall s": 2.0, "kind": "a"}])
    assert med == {"wall s": 2.0, "kind": "a"}
    text = run.table("x", ({"wall s": 2.0}, None), ({"wall s": 1.0}, None), "main")
    assert "| wall s | 2 | 1 | 0.5 |" in text
    text = run.table("x", (None, "ImportError: no module"), ({"wall s": 1.0}, None), "main")
    assert "| wall s | ImportError: no module | 1 |  |" in text


def test_an_unknown_group_is_refused():
    r = subprocess.run([sys.executable, os.path.join(BENCH, "run.py"), "nogroup", "--no-base"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "unknown group(s) nogroup" in r.stderr


def test_the_continuation_benchmark_measures_against_the_committed_tables():
    """The committed deep tables against themselves give zero; a pulse shifted by δβ and a
    relative δL shows exactly those; a pulse outside the tables' span is not compared."""
    import numpy as np
    suite = _load("suite")
    ref = suite._committed_tables()
    assert len(ref) > 100 and np.all(np.diff(ref[:, 0]) > 0)
    assert ref[-1, 0] == 1.2 and ref[0, 0] < 1.01
    new = ref[::7].copy()
    db, dl, n = suite._against(new, ref)
    assert n == len(new) and db < 1e-14 and dl < 1e-14
    new[3, 1] += 2e-6
    new[5, 2] *= 1 + 3e-5
    outside = np.array([[1.3, 0.0, 1.0]])
    db, dl, n = suite._against(np.vstack([new, outside]), ref)
    assert n == len(new)
    assert db == pytest.approx(2e-6, rel=1e-6) and dl == pytest.approx(3e-5, rel=1e-6)
