"""benchmarks/march_log_stats.py reads a family log's progress bar into where the time went."""
import importlib.util
import os

import pytest

_PATH = os.path.join(os.path.dirname(__file__), os.pardir, "benchmarks", "march_log_stats.py")
_spec = importlib.util.spec_from_file_location("march_log_stats", _PATH)
mls = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mls)

BAR = "family: 100%|##########| 39.0/39 "
LOG = "\r".join([
    BAR + "[00:30<00:00, 1.00837 beta=0.998589 L=7000m]",
    "at tau_d/tau_min=1.0083715 (L=7000.0 m): healing-front zone moved by +58.86 m onto its drop",
    BAR + "[01:10<00:00, 1.00837 failed (1): arclength step ds=0.002 (N=6614, 7 it.) ]",
    BAR + "[01:40<00:00, 1.00837 beta=0.998590 L=7020m]",
    BAR + "[02:00<00:00, 1.00837 beta=0.998590 L=7050m]",
    BAR + "[02:00<00:00, 1.00837 beta=0.998590 L=7050m]",           # the bar redrawn: one event
    "grid check at tau_d/tau_min=1.0083700: N=6614 vs 13227: dbeta=8.4e-10 dL/L=2.0e-05",
    BAR + "[05:00<00:00, 1.00837 beta=0.998590 L=7050m]",
    BAR + "[1:05:30<00:00, 1.00837 beta=0.998591 L=7080m]",
])
# above 10 km: the bar with L in 4 digits and with L in 5 digits
LOG_10KM = "\r".join([BAR + "[00:30<00:00, 1.00826 beta=0.998727 L=9993m]",
                       BAR + "[01:00<00:00, 1.00826 beta=0.998727 L=1.002e+04m]",
                       BAR + "[01:30<00:00, 1.00826 beta=0.998728 L=10111m]"])


def test_lengths_above_10_km_are_read():
    s = mls.stats(mls.events(LOG_10KM))
    assert (s["L0"], s["L1"], s["accepted"]) == (9993, 10111, 2)


def test_the_log_is_read_into_steps_failures_and_checks():
    s = mls.stats(mls.events(LOG))
    assert (s["L0"], s["L1"]) == (7000, 7080)
    assert s["failed"] == 1 and s["t_failed"] == 40 and s["iterations"] == [7]
    assert s["accepted"] == 3 and s["t_accepted"] == 30 + 20 + (3930 - 300)
    assert s["checks"] == 1 and s["t_checks"] == 180 and s["recentred"] == 1
    march = 40 + 30 + 20 + 3630
    assert s["km_h"] == pytest.approx(80 / march * 3.6)
    assert s["km_h_all"] == pytest.approx(80 / (march + 180) * 3.6)
