#!/usr/bin/env bash
# Creates/updates the bench-only venv .venv-bench (onnxruntime + onnx, the MLP latency reference of
# `make bench`), pinned by tests/bench/requirements-bench.txt. Kept apart from .venv on purpose: the runtime
# and the project venv must never depend on onnxruntime. Re-installs only when the requirements change.
#   tools/bench_env.sh            create or update, print the venv's python path
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

REQ=tests/bench/requirements-bench.txt
VENV=.venv-bench
PY=${PYTHON:-python3}
stamp=$VENV/.requirements.sha
want=$(sha256sum "$REQ" | cut -d' ' -f1)
if [[ ! -x $VENV/bin/python || ! -f $stamp || "$(cat "$stamp")" != "$want" ]]; then
  echo "bench_env: creating/updating $VENV from $REQ" >&2
  [[ -x $VENV/bin/python ]] || "$PY" -m venv "$VENV"
  $VENV/bin/pip install -q --upgrade pip >&2
  $VENV/bin/pip install -q -r "$REQ" >&2
  echo "$want" > "$stamp"
fi
echo "$PWD/$VENV/bin/python"
