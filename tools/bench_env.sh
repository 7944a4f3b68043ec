#!/usr/bin/env bash
# Creates/updates the bench-only venv .venv-bench (onnxruntime + onnx, the MLP latency reference of
# `make bench`), pinned by tests/bench/requirements-bench.txt. Kept apart from .venv on purpose: the runtime
# and the project venv must never depend on onnxruntime. Re-installs only when the requirements change.
#   tools/bench_env.sh            create or update (needs the package registry: run it OUTSIDE tools/netns,
#                                 as `make bench-env` / `make bench` do), print the venv's python path
#   tools/bench_env.sh --check    install nothing: print the python path if the venv is up to date, else
#                                 say how to make it and exit 1 (what the benchmark runs inside the namespace)
# BENCH_VENV overrides the venv directory (tests).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

REQ=tests/bench/requirements-bench.txt
VENV=${BENCH_VENV:-.venv-bench}
PY=${PYTHON:-python3}
stamp=$VENV/.requirements.sha
want=$(sha256sum "$REQ" | cut -d' ' -f1)
up_to_date() { [[ -x $VENV/bin/python && -f $stamp && "$(cat "$stamp")" == "$want" ]]; }

if [[ "${1:-}" == "--check" ]]; then
  if ! up_to_date; then
    echo "bench_env: $VENV is missing or older than $REQ: run \`make bench-env\` (outside the network namespace)" >&2
    exit 1
  fi
elif ! up_to_date; then
  if [[ "${T1_NETNS_INSIDE:-}" == "1" ]]; then
    # The project namespace has only loopback: pip would fail on name resolution. Refuse clearly instead.
    echo "bench_env: cannot install $VENV inside the network namespace (no registry there): run \`make bench-env\` outside it" >&2
    exit 1
  fi
  echo "bench_env: creating/updating $VENV from $REQ" >&2
  [[ -x $VENV/bin/python ]] || "$PY" -m venv "$VENV"
  $VENV/bin/pip install -q --upgrade pip >&2
  $VENV/bin/pip install -q -r "$REQ" >&2
  echo "$want" > "$stamp"
fi
echo "$PWD/$VENV/bin/python"
