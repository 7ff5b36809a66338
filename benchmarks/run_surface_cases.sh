#!/bin/sh
# Run bench_surface.py one case per process, one after the other, one BLAS thread, a log
# per case: benchmarks/run_surface_cases.sh LOGDIR "METHODS" CASE [CASE ...]
# (extra flags for every run in $BENCH_FLAGS, e.g. "--markdown --every-frame").
set -u
out=$1 methods=$2
shift 2
mkdir -p "$out"
here=$(dirname "$0")
for case in "$@"; do
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
        python "$here/bench_surface.py" --cases "$case" --methods "$methods" \
        ${BENCH_FLAGS:-} > "$out/$case.log" 2>&1
    echo "$case: exit $?" >> "$out/done.txt"
done
