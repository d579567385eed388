"""The documentation site (docs/: MyST pages + the API reference from the numpydoc docstrings)
builds with warnings as errors, by the one command the README gives."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_docs_site_builds_without_warnings(tmp_path):
    try:
        import myst_parser  # noqa: F401
        import sphinx  # noqa: F401
    except ImportError as exc:  # a failure, not a skip: the test extra installs them
        raise AssertionError(f"{exc}: install the test extra, pip install -e '.[test]'") from exc
    out = tmp_path / "html"
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(ROOT / "docs"), str(out)],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-4000:]
    # the pages and the API reference are there, with the documented functions in them
    api = (out / "api.html").read_text(encoding="utf-8")
    assert 'id="slippulse.steady.solver.solve_pulse"' in api
    for page in ("index", "results", "guide", "stability", "spectrum", "steady"):
        assert (out / f"{page}.html").is_file(), page


def _readme_commands():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return [line.strip() for line in text.splitlines()
            if line.startswith("    python3 -m venv .venv")]


def test_readme_has_the_two_commands_and_ci_runs_the_second():
    main_job, tests = _readme_commands()
    assert main_job.endswith("slippulse steady solve --tau-d 1.2 --overwrite && slippulse dynamic verify "
                             "--steady runs/steady/td1.2000.h5 --label td1.2000 --distance 0.2 "
                             "--out runs/dynamic/verify_td1.2000.h5 --overwrite")
    assert "pip install -q -e . &&" in main_job
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()
          if line.startswith("python3 -m venv")]
    assert ci == [tests]
