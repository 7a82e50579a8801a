#!/usr/bin/env bash
# The identification battery in parallel: every case of tests/battery in its own single-threaded
# process (bench/battery_table.py and bench/battery_predict.py), as many at once as there are
# cores. Logs and JSON per case under OUT (default bench-out/). Slow per case: on a 16-core machine
# no single-threaded case had finished after 520 s (truth machine 40 × 20, fit, prediction); give
# each case several threads (edit XLA_FLAGS) where cores allow. Run from the repository root:
#     bash bench/battery_parallel.sh [OUT]
set -u
OUT=${1:-bench-out}
mkdir -p "$OUT"
export JAX_PLATFORMS=${JAX_PLATFORMS:-cpu}
export XLA_FLAGS="${XLA_FLAGS:-} --xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
PY=${PYTHON:-python}
CASES=$($PY -c "import sys; sys.path.insert(0, 'tests'); from battery.cases import CASES; print(' '.join(CASES))")
jobs=()
for c in $CASES; do
  jobs+=("$PY bench/battery_table.py $c --json $OUT/table_$c.json > $OUT/table_$c.log 2>&1")
  jobs+=("$PY bench/battery_predict.py $c --json $OUT/predict_$c.json > $OUT/predict_$c.log 2>&1")
done
printf '%s\n' "${jobs[@]}" | xargs -P "$(nproc)" -I{} bash -c '{}'
