#!/bin/bash
# The GPU runs of docs/stability.md §10.8, in order of priority, within one budget of seconds.
#
#   bash dynamic/gpu_runs.sh [BUDGET_S]      (repository root, a machine with CuPy and a GPU;
#                                              runs/s41/fam2000.h5 as made in dynamic/scans/gpu_td1.10.toml)
#
# 1. tests/test_device.py: the CUDA kernels against the host (rounding only);
# 2. gpu_td1.10: a pair the host measured (7.9803 +- 0.0025 per L), the engine's check;
# 3. gpu_td1.04: +-3e-3 pair on 96 L at 4 mm over 10 L; 4. gpu_td1.03 (220 L, 8 mm, 20 L);
# 5. gpu_td1.04_checks: period, eps, grid; 6. the 1.1 pair on the host CPUs (speed, side by side).
# Each stage is cut at what is left of the budget; finished cases stay (one file per case).
# The case files, without their slip-rate snapshots, go to $OUT/scans.tar.gz (default runs/s41/gpu).
set -u
PY=${PYTHON:-python3}
BUDGET=${1:-540}
OUT=${OUT:-runs/s41/gpu}
mkdir -p "$OUT"
export PYTHONPATH=$PWD/src PYTHONUNBUFFERED=1 NUMBA_CACHE_DIR=/tmp/slippulse_numba
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
left() { echo $(( BUDGET - 40 - SECONDS )); }
stage() {  # stage NAME CAP COMMAND...: run with min(CAP, what is left) seconds
    local name=$1 cap=$2; shift 2
    local t; t=$(left); [ "$t" -gt "$cap" ] && t=$cap
    if [ "$t" -lt 20 ]; then echo "== $name: skipped (budget)"; return; fi
    echo "== $name: up to $t s (at $SECONDS s)"
    timeout -k 15 -s TERM "$t" "$@" > "$OUT/$name.log" 2>&1
    echo "== $name: exit $? at $SECONDS s"; tail -n 4 "$OUT/$name.log"
    pkill -f spawn_main 2>/dev/null; sleep 1          # no worker of a cut stage left on the GPU
}
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
stage pytest 150 $PY -m pytest -q -x -p no:cacheprovider tests/test_device.py
stage td1.10 90 $PY -m slippulse dynamic scan dynamic/scans/gpu_td1.10.toml --workers 2 --no-progress
stage td1.04 300 $PY -m slippulse dynamic scan dynamic/scans/gpu_td1.04.toml --workers 2 --no-progress
stage td1.03 300 $PY -m slippulse dynamic scan dynamic/scans/gpu_td1.03.toml --workers 2 --no-progress
stage td1.04_checks 300 $PY -m slippulse dynamic scan dynamic/scans/gpu_td1.04_checks.toml --workers 2 --no-progress
sed 's/device = "cupy"/device = "cpu"/; s#runs/scans/gpu_td1.10#runs/scans/cpu_td1.10#; s/name = "gpu_td1.10"/name = "cpu_td1.10"/' \
    dynamic/scans/gpu_td1.10.toml > /tmp/cpu_td1.10.toml
stage cpu_td1.10 120 $PY -m slippulse dynamic scan /tmp/cpu_td1.10.toml --workers 2 --no-progress
$PY - "$OUT" <<'PY'
import glob, os, sys, tarfile, h5py
out = sys.argv[1]
with tarfile.open(os.path.join(out, "scans.tar.gz"), "w:gz") as tar:
    for d in sorted(glob.glob("runs/scans/*_td1.*")):
        for f in sorted(glob.glob(os.path.join(d, "*"))):
            if f.endswith(".png"):
                continue
            if f.endswith(".h5") and not os.path.basename(f).startswith("summary"):
                small = f + ".small"
                with h5py.File(f, "r") as h, h5py.File(small, "w") as s:
                    for k, v in h.attrs.items():
                        s.attrs[k] = v
                    for k in h:
                        if k != "snapshots":
                            h.copy(k, s)
                    if "snapshots" in h:
                        g = s.create_group("snapshots")
                        for k in ("t", "x_front"):
                            h.copy(f"snapshots/{k}", g)
                tar.add(small, arcname=f)
                os.remove(small)
                continue
            tar.add(f)
print("packed", os.path.getsize(os.path.join(out, "scans.tar.gz")), "bytes")
PY
echo "== done at $SECONDS s"
