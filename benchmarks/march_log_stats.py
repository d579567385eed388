"""Where a deep march's wall time went, read from the log of `slippulse steady family`.

    python benchmarks/march_log_stats.py runs/deep/deep.log [more logs]

Per log: the L it covered, the accepted steps, the failed attempts (with their Newton iterations)
and the grid checks, each with the wall time between the progress bar's updates, and the march's
pace without and with the checks. The intervals come from the bar's elapsed times (whole
seconds); the first interval after a resume includes the start. A measurement of a run as it
went (its load is whatever ran beside it), not a side-by-side benchmark.
"""
from __future__ import annotations

import argparse
import re


def _seconds(t: str) -> int:
    parts = [int(x) for x in t.split(":")]
    return parts[0] * 3600 + parts[1] * 60 + parts[2] if len(parts) == 3 else parts[0] * 60 + parts[1]


def events(text: str) -> list:
    """(kind, elapsed s or None, L m or iterations) per line: 'A' an accepted step, 'F' a failed
    attempt, 'C' a grid check, 'R' the zone moved onto the healing front (recentre)."""
    out = []
    for line in text.replace("\r", "\n").split("\n"):
        m = re.search(r"\[(\d+:\d+(?::\d+)?)<[^,]*, ([\d.]+) (.*)\]", line)
        if m:
            t, rest = _seconds(m.group(1)), m.group(3)
            if rest.startswith("failed"):
                it = re.search(r"(\d+) it", rest)
                ev = ("F", t, int(it.group(1)) if it else -1)
            else:
                # L as the bar prints it: "L=9776m", "L=10111m"; older logs print 4 digits, so
                # "L=1.007e+04m" above 10 km
                L = re.search(r"L=(\d+(?:\.\d+)?(?:e\+\d+)?)m", rest)
                if not L:
                    continue
                ev = ("A", t, round(float(L.group(1))))
        elif "grid check at" in line and "by region" not in line:
            ev = ("C", None, None)
        elif "healing-front zone moved" in line:
            ev = ("R", None, None)
        else:
            continue
        if not out or ev != out[-1]:
            out.append(ev)
    return out


def stats(evs: list) -> dict:
    t_prev, L0, L1 = None, None, None
    acc, fail, chk, its, recentred = [], [], [], [], 0
    after_check = False
    for kind, t, val in evs:
        if kind == "C":
            after_check = True
            continue
        if kind == "R":
            recentred += 1
            continue
        if t_prev is not None:
            dt = t - t_prev
            if after_check:
                chk.append(dt)            # the bar's first update after a check: its time
            elif kind == "A":
                acc.append(dt)
            else:
                fail.append(dt)
                its.append(val)
        after_check = False
        if kind == "A":
            L0 = val if L0 is None else L0
            L1 = val
        t_prev = t
    march = sum(acc) + sum(fail)
    return {"L0": L0, "L1": L1, "accepted": len(acc), "t_accepted": sum(acc),
            "failed": len(fail), "t_failed": sum(fail), "iterations": its,
            "checks": len(chk), "t_checks": sum(chk), "recentred": recentred,
            "km_h": (L1 - L0) / march * 3.6 if march else float("nan"),
            "km_h_all": (L1 - L0) / (march + sum(chk)) * 3.6 if march + sum(chk) else float("nan")}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("logs", nargs="+", help="logs of `slippulse steady family` (stderr)")
    args = ap.parse_args(argv)
    for path in args.logs:
        with open(path, "rb") as fh:
            s = stats(events(fh.read().decode("utf-8", "replace")))
        if s["L0"] is None:
            print(f"{path}: no accepted step")
            continue
        print(f"{path}: L {s['L0']} -> {s['L1']} m; accepted {s['accepted']} "
              f"({s['t_accepted'] / 60:.1f} min), failed {s['failed']} "
              f"({s['t_failed'] / 60:.1f} min; iterations {s['iterations']}), grid checks "
              f"{s['checks']} ({s['t_checks'] / 60:.1f} min), recentred {s['recentred']}; "
              f"{s['km_h']:.2f} km/h without the checks, {s['km_h_all']:.2f} km/h with them")


if __name__ == "__main__":
    main()
