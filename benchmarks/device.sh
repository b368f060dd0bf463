#!/usr/bin/env bash
# The figures that need the lent GPU machine (16 cores, one NVIDIA GPU), one stage a call:
#
#   bash benchmarks/device.sh gpu     # bench --backend cuda, shipped maps on both backends, headline
#   bash benchmarks/device.sh map     # the 1e8-launch map (sweeps/gpu-1e8.toml): wall and peak memory
#   bash benchmarks/device.sh cpu     # 16-core scaling of the square map, bench on 2 and 16 cores
#   bash benchmarks/device.sh headline   # bench --headline --backend cuda; sweep --backend cuda
#   bash benchmarks/device.sh scaling [N]   # bench --scaling on the headline map (N = 100: 1e6
#                                           # launches) on 1 thread, 16 threads, 16 dask workers
#   bash benchmarks/device.sh quadrature   # the headline and the 1e8 map by quadrature on the GPU
#   (also: map-n N, an N^3 map of the same box; observer, the kernel with and without samples)
#
# The machine has its own Python with numba, numba-cuda, numpy, xarray, pandas and matplotlib and
# no package index: netCDF4, cftime and dask come as wheels in .whl/ (docs/performance.md, "On a GPU").
# Logs go to $OUT (or ./device-out) as <stage>.log.
set -uo pipefail
cd "$(dirname "$0")/.."
stage=${1:?stage: gpu, map or cpu}
out=${OUT:-device-out}
mkdir -p "$out"
if ls .whl/*.whl >/dev/null 2>&1; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || exit 1
    export PYTHONPATH=/tmp/site:$PWD/src
else
    export PYTHONPATH=$PWD/src
fi
export PYTHONUNBUFFERED=1 MPLBACKEND=Agg
export BALLSURVEY_CACHE_DIR=$PWD/.devcache/ballsurvey NUMBA_CACHE_DIR=$PWD/.devcache/numba
log="$out/$stage.log"

{
    echo "== $(date -u +%FT%TZ) stage $stage"
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>&1 | head -2
    lscpu | grep -E "^Model name|^CPU\(s\)|^Thread|^Core|^Socket|^Flags" | cut -c1-200 | tr -s ' '
    grep -o "avx512[a-z]*\|avx2\|fma" /proc/cpuinfo | sort -u | tr "\n" " "; echo
    python3 -c "import numba, numpy; print('numba', numba.__version__, 'numpy', numpy.__version__)"
    case $stage in
    gpu)
        timeout 540 python3 benchmarks/gpu_check.py ;;
    map)
        python3 benchmarks/peak.py timeout -s INT 560 python3 -m ballsurvey sweep \
            sweeps/gpu-1e8.toml -o /tmp/gpu-1e8.nc --no-progress -v --force
        ls -la /tmp/gpu-1e8.nc 2>&1 ;;
    quadrature)  # the headline map by quadrature on the GPU (dop853 on the CPU beside it), then
                 # the 1e8-launch quadrature map on the GPU, stopped at 300 s if not done
        timeout 300 python3 -m ballsurvey bench --headline --method quadrature --backend cuda
        python3 benchmarks/peak.py timeout -s INT 300 python3 -m ballsurvey sweep \
            sweeps/quadrature-1e8.toml --backend cuda -o /tmp/q1e8.nc --no-progress -v --force
        ls -la /tmp/q1e8.nc 2>&1 ;;
    map-n)  # the same box at N points an axis (N^3 launches): bash benchmarks/device.sh map-n 215
        n=${2:?N}
        sed "s/num = 464/num = $n/" sweeps/gpu-1e8.toml > /tmp/gpu-n.toml
        python3 benchmarks/peak.py timeout -s INT 400 python3 -m ballsurvey sweep \
            /tmp/gpu-n.toml -o /tmp/gpu-n.nc --no-progress -v --force
        ls -la /tmp/gpu-n.nc 2>&1 ;;
    observer)  # the CUDA kernel with and without the observer (a sample every 4 steps, or none)
        python3 -m ballsurvey bench --backend cuda --launches 1048576 --observe-every 4
        python3 -m ballsurvey bench --backend cuda --launches 1048576 --observe-every 1000000 ;;
    headline)  # the CLI's own GPU commands: the 1e6-launch headline, and a spec run with --backend
        timeout 200 python3 -m ballsurvey bench --headline --backend cuda
        timeout 100 python3 -m ballsurvey sweep sweeps/square-map.toml --backend cuda \
            -o /tmp/square-cuda.nc --force -v --no-progress ;;
    map-resume)
        python3 benchmarks/peak.py timeout -s INT 560 python3 -m ballsurvey sweep \
            sweeps/gpu-1e8.toml -o /tmp/gpu-1e8.nc --no-progress -v --resume
        ls -la /tmp/gpu-1e8.nc 2>&1 ;;
    scaling)  # the fixed cost per process, each run's kernels and rest, identical maps
        timeout 590 python3 -m ballsurvey bench --scaling --headline "${2:-100}" --threads 16 \
            --workers 16 ;;
    cpu)
        timeout 330 python3 -m ballsurvey bench --scaling sweeps/square-map.toml --threads 16 \
            --workers 16
        echo "-- bench on 2 cores (taskset -c 0,1, 2 numba threads)"
        NUMBA_NUM_THREADS=2 timeout 120 taskset -c 0,1 python3 -m ballsurvey bench
        echo "-- bench on 16 cores"
        timeout 90 python3 -m ballsurvey bench ;;
    *)
        echo "unknown stage $stage"; exit 2 ;;
    esac
    echo "== $(date -u +%FT%TZ) done"
} 2>&1 | tee "$log"
