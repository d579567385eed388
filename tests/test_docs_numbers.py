"""Numbers quoted in README.md and the docs agree with the results file of record.

Convention (docs/results/records.toml, header): a number of record is written in Markdown as
``22.654 ± 2e−5<!-- rec spectrum_nested/td1.2000/s_per_L -->`` — the number, optionally ``± err`` and
bold markers, then an HTML comment naming its key in the results file ("/" between the parts).
The quote must be the recorded value rounded to the digits quoted (and so must its ``± err``).
"""
import math
import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RECORDS = ROOT / "docs" / "results" / "records.toml"
DOCS = [ROOT / "README.md", ROOT / "BENCHMARKS.md", ROOT / "steady" / "README.md",
        ROOT / "dynamic" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

NUM = r"[−-]?\d+(?:\.\d+)?(?:[eE][−+-]?\d+)?"
QUOTE = re.compile(rf"({NUM})(?:\s*±\s*({NUM}))?\**\s*<!--\s*rec\s+(\S+)\s*-->")
MARKER = re.compile(r"<!--\s*rec\b")


def _float(text):
    return float(text.replace("−", "-"))


def _half_ulp(text):
    """Half a unit in the last digit quoted: the largest rounding error the quote may carry."""
    mantissa, _, exponent = text.replace("−", "-").lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (-decimals + (int(exponent) if exponent else 0))


def _lookup(records, key):
    node = records
    for part in key.split("/"):
        if not isinstance(node, dict) or part not in node:
            raise KeyError(key)
        node = node[part]
    return node


def check_text(text, records, where="text"):
    """Problems with the quoted numbers of ``text``: one line each (empty: all agree)."""
    problems, found = [], 0
    for m in QUOTE.finditer(text):
        found += 1
        value_text, err_text, key = m.groups()
        line = text.count("\n", 0, m.start()) + 1
        try:
            record = _lookup(records, key)
        except KeyError:
            problems.append(f"{where}:{line}: {key} is not in {RECORDS.name}")
            continue
        value, err = (record.get("value"), record.get("err")) if isinstance(record, dict) else (record, None)
        if not isinstance(value, (int, float)):
            problems.append(f"{where}:{line}: {key} is not a number in {RECORDS.name}")
            continue
        tol = _half_ulp(value_text) * (1 + 1e-9)
        if not abs(_float(value_text) - value) <= tol:
            problems.append(f"{where}:{line}: quoted {value_text} for {key}, record {value}")
        if err_text is not None:
            if err is None:
                problems.append(f"{where}:{line}: quoted ± {err_text} for {key}, record has no err")
            elif not abs(_float(err_text) - err) <= _half_ulp(err_text) * (1 + 1e-9):
                problems.append(f"{where}:{line}: quoted ± {err_text} for {key}, record err {err}")
    if found != len(MARKER.findall(text)):
        problems.append(f"{where}: {len(MARKER.findall(text)) - found} marker(s) not preceded by a number")
    return problems, found


@pytest.fixture(scope="module")
def records():
    return tomllib.loads(RECORDS.read_text(encoding="utf-8"))


def test_quoted_numbers_match_the_records(records):
    problems, total = [], 0
    for path in DOCS:
        p, n = check_text(path.read_text(encoding="utf-8"), records, path.relative_to(ROOT))
        problems += p
        total += n
    assert not problems, "\n".join(problems)
    # the convention is in use: the results page quotes the numbers of record through it
    assert total >= 30, total


def test_every_record_names_its_provenance(records):
    provenance = records["provenance"]
    for entry in provenance.values():
        for field in ("command", "commit", "date", "machine", "how"):
            assert entry.get(field), (entry, field)

    def groups(node, path=""):
        if isinstance(node, dict) and "provenance" in node and isinstance(node["provenance"], str):
            yield path, node
        elif isinstance(node, dict):
            for k, v in node.items():
                if k != "provenance":
                    yield from groups(v, f"{path}/{k}")
    seen = list(groups({k: v for k, v in records.items() if k != "provenance"}))
    assert len(seen) >= 10
    for path, node in seen:
        assert node["provenance"] in provenance, path
    for key, value in records.items():  # no record outside a group with provenance
        assert key == "provenance" or isinstance(value, dict), key


def test_the_check_fails_on_a_changed_number(records):
    good = "s = **22.654 ± 2e−5**<!-- rec spectrum_nested/td1.2000/s_per_L --> per L"
    assert check_text(good, records) == ([], 1)
    for bad in ("s = 22.655 ± 2e−5<!-- rec spectrum_nested/td1.2000/s_per_L -->",     # value off by 1 ulp
                "s = 22.654 ± 3e−5<!-- rec spectrum_nested/td1.2000/s_per_L -->",     # error off
                "s = 22.65<!-- rec spectrum_nested/td1.2000/no_such_key -->",          # unknown key
                "s = 22.6<!-- rec spectrum_nested/td1.2000/s_per_L -->",               # rounded wrongly
                "s = about<!-- rec spectrum_nested/td1.2000/s_per_L -->"):             # no number
        problems, _ = check_text(bad, records)
        assert problems, bad


def test_half_ulp():
    assert math.isclose(_half_ulp("22.654"), 5e-4)
    assert math.isclose(_half_ulp("2e−5"), 5e-6)
    assert math.isclose(_half_ulp("1.35e-3"), 5e-6)
    assert math.isclose(_half_ulp("1586"), 0.5)


def test_provenance_and_keys_name_no_episode_of_the_work():
    """Provenance is the command, the commit, the date and the load; keys say what they hold.
    Neither names an episode of the work (the patterns of tests/test_no_history.py)."""
    from test_no_history import history_words
    text = RECORDS.read_text(encoding="utf-8")
    assert not history_words(text), history_words(text)
