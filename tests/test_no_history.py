"""No development history in the product: the episodes of the work (numbered stops, issues, and the
short episode tokens made of an ``s`` and two digits, alone or after an underscore) belong in
``git log``, not in a tracked file's content or name. The patterns match those words only: units,
symbols and variable names (``s_err``, ``s L/c_p``, ``1e-3 s``) are not episode tokens."""
import os
import re
import subprocess

import pytest

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir)

#: the history words: a numbered stop or issue ("stop-44", "stops 43–47", "issue #17",
#: "stop37") and a two-digit episode token ("s41", "_s47", "runs/s36/")
PATTERNS = [
    re.compile(r"(?:\b|(?<=_))stops?[ \-_]?#?\d+", re.IGNORECASE),
    re.compile(r"(?:\b|(?<=_))issues?[ \-_]?#?\d+", re.IGNORECASE),
    re.compile(r"(?:\b|(?<=_))s\d{2}(?=\b|_)"),
]


def history_words(text):
    """The history words of ``text``, in order (empty when it has none)."""
    return [m.group(0) for p in PATTERNS for m in p.finditer(text)]


def tracked_files():
    """The repository's tracked files (paths relative to its root); None outside a git checkout."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    return [p for p in out.stdout.decode().split("\0") if p]


#: this file, whose examples of the patterns are history words by design
SELF = "tests/test_no_history.py"


def offenders(paths=None):
    """Each tracked file name and text line that holds a history word, as "path:line: text"
    (line 0: the name itself). Binary files are checked by name only; this file is skipped."""
    found = []
    for path in tracked_files() if paths is None else paths:
        if path == SELF:
            continue
        if history_words(path):
            found.append(f"{path}:0: (file name)")
        full = os.path.join(ROOT, path)
        if not os.path.isfile(full):
            continue
        with open(full, "rb") as f:
            data = f.read()
        if b"\0" in data[:8192]:
            continue
        for i, line in enumerate(data.decode("utf-8", errors="replace").splitlines(), 1):
            if history_words(line):
                found.append(f"{path}:{i}: {line.strip()[:120]}")
    return found


@pytest.mark.parametrize("text, words", [
    ("the rule before stop 33", ["stop 33"]),
    ("stops 43–47 and the stop-44 seed", ["stops 43", "stop-44"]),
    ("spectrum_rates_stop37.png", ["stop37"]),
    ("issue 17, item 5; Issue #4", ["issue 17", "Issue #4"]),
    ("deep_seed_s46.h5 and runs/s41/fam2000.h5", ["s46", "s41"]),
    ("gpu_s43_td1.05.toml", ["s43"]),
    ("s_err = 1e-3 s; s L/c_p = 0.31; 20 s per step; cells 10 s2n x12s34", []),
    ("the solver stops when |r| < 1e-13; a non-issue; s1 and s123", []),
])
def test_the_patterns_find_history_words_and_nothing_else(text, words):
    assert history_words(text) == words


def test_no_tracked_file_names_an_episode_of_the_work():
    files = tracked_files()
    if files is None:
        pytest.skip("not a git checkout")
    bad = offenders(files)
    assert not bad, f"{len(bad)} lines name episodes of the work:\n" + "\n".join(bad[:50])



def test_the_scan_reads_lines_and_names(tmp_path):
    """offenders() finds the words in a file's lines and in its name (a scan that read nothing
    would let the test above pass), and skips this file."""
    f = tmp_path / "notes.txt"
    f.write_text("a clean line\nthe rule before stop 33\n")
    rows = offenders([str(f), "a/deep_seed_s46.h5", SELF])
    assert rows == [f"{f}:2: the rule before stop 33", "a/deep_seed_s46.h5:0: (file name)"]


if __name__ == "__main__":
    for row in offenders():
        print(row)
