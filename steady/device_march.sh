#!/bin/bash
# The deep march (`slippulse steady family`, resumed from FILE) on a lent device machine's CPU
# cores for a fixed wall time, then FILE copied to $OUT. The march is stopped with kill -9, which
# leaves the family file intact (tests/test_kill_safety.py); rerunning the same command here goes
# on from its deepest pulse. Takes SECONDS plus the imports and numba compiles (~1 min).
#
#   bash steady/device_march.sh FILE SECONDS [slippulse steady family options ...]
#
# Run on a lent GPU machine's host cores (16 cores, one process), the family file carried there.
set -u
f=$1; secs=$2; shift 2
n=$(getconf _NPROCESSORS_ONLN)
export PYTHONPATH=$PWD/src PYTHONUNBUFFERED=1 OMP_NUM_THREADS=$n OPENBLAS_NUM_THREADS=$n \
    MKL_NUM_THREADS=$n NUMBA_NUM_THREADS=$n
out=${OUT:-/tmp}
echo "cores: $n; load: $(cat /proc/loadavg)"
python3 - <<'PY' || exit 1
import time, numpy as np, scipy.linalg as sla
import h5py, numba, tqdm                        # noqa: F401 - what the march needs
import slippulse.cli.app                        # noqa: F401
for n in (5063, 10125):
    a = np.random.default_rng(0).standard_normal((n, n))
    t = time.perf_counter(); sla.lu_factor(a, overwrite_a=True, check_finite=False)
    print(f"LU of {n}: {time.perf_counter() - t:.2f} s", flush=True)
PY
timeout -s KILL "$secs" python3 -m slippulse steady family --out "$f" "$@" > "$out/march.log" 2>&1
echo "march: exit $? after at most $secs s"
cp "$f" "$out/"
tr '\r' '\n' < "$out/march.log" | grep -v '^ *$' | tail -4
