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


def test_the_suite_has_the_six_groups_each_with_a_benchmark():
    suite = _load("suite")
    assert list(suite.GROUPS) == ["steady", "family", "deep", "spectrum", "sbi", "gpu"]
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
