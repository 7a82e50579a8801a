#!/usr/bin/env bash
# The newest end of the test matrix: the newest jax, jaxlib and equinox that pip finds (jax >= 0.11
# needs Python >= 3.12), with the test tools of the [test-newest] extra, in a venv of its own; then
# the fast subset of the suite. The pinned low end is .ci/run ([test] = [test-newest] + [pinned]).
#
#   bash bench/test_matrix.sh [PYTHON] [VENV]     (defaults: python3.12, /tmp/diffguide-newest)
#
# It prints the versions it tested (pip freeze) and pytest's summary; the venv is kept, so a
# second call only re-runs the tests (and upgrades what has a newer release).
set -euo pipefail
PY=${1:-python3.12}
VENV=${2:-/tmp/diffguide-newest}
ROOT=$(cd "$(dirname "$0")/.." && pwd)

[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q -e "$ROOT[test-newest]"
"$VENV/bin/python" -m pip install -q --upgrade jax jaxlib equinox jaxtyping
"$VENV/bin/python" --version
"$VENV/bin/python" -m pip freeze | grep -iE "^(jax|jaxlib|equinox|jaxtyping|numpy|scipy)==" || true

cd "$ROOT"
timeout 3600 "$VENV/bin/python" -m pytest -x -q \
    tests/test_compat.py tests/test_stack.py tests/test_aot.py tests/test_contact.py \
    tests/test_guideway.py tests/test_machine.py tests/test_newton_condensed.py \
    tests/test_fe_condense.py tests/test_table_cache.py tests/test_api_edges.py \
    tests/test_inverse.py
