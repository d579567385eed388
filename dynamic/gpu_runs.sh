#!/bin/bash
# One scan on a GPU machine within a budget of seconds, its results packed small.
#
#   bash dynamic/gpu_runs.sh BUDGET_S SCAN.toml [WORKERS]     (repository root; CuPy and a GPU)
#
# e.g. bash dynamic/gpu_runs.sh 215 dynamic/scans/gpu_check_and_pairs.toml 4 (docs/stability.md §2.8; the
# pulses and spectra of runs/steady/fam2000.h5 as in dynamic/scans/gpu_td1.10.toml). The scan is cut
# at BUDGET_S seconds; finished cases stay (one file per case). Its directory, the case files
# without their slip-rate snapshots, goes to $OUT/<scan name>.tar.gz (default OUT: runs/gpu).
set -u
PY=${PYTHON:-python3}
BUDGET=$1; SCAN=$2; WORKERS=${3:-2}
OUT=${OUT:-runs/gpu}
mkdir -p "$OUT"
export PYTHONPATH=$PWD/src PYTHONUNBUFFERED=1 NUMBA_CACHE_DIR=/tmp/slippulse_numba
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
name=$(basename "$SCAN" .toml)
timeout -k 10 -s TERM "$BUDGET" $PY -m slippulse dynamic scan "$SCAN" --workers "$WORKERS" \
    --no-progress > "$OUT/$name.log" 2>&1
echo "== scan exit $? at $SECONDS s"; tail -n 8 "$OUT/$name.log"
pkill -f spawn_main 2>/dev/null
dir=$($PY -c "import sys, tomllib; print(tomllib.load(open(sys.argv[1], 'rb'))['scan']['out_dir'])" "$SCAN")
$PY - "$OUT/$name.tar.gz" "$dir" <<'PY'
import glob, os, sys, tarfile, h5py
dest, d = sys.argv[1], sys.argv[2]
with tarfile.open(dest, "w:gz") as tar:
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
        else:
            tar.add(f)
print("packed", dest, os.path.getsize(dest), "bytes")
PY
echo "== done at $SECONDS s"
