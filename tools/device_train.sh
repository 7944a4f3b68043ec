#!/usr/bin/env bash
# Training on the lent GPU machine (docs/device.md). Its python3 (3.12) has JAX with CUDA; the rest of the
# project's training dependencies travel as cp312 wheels in .whl/.
#
#   tools/device_train.sh start NAME -- ARGS...   install wheels, start `python -m training ARGS
#        --out $RUNS/NAME` detached (setsid), log $RUNS/NAME.log (RUNS=/root/t1runs). ARGS is a subcommand:
#        `train TASK ...` (NAME is the run) or `recipe RECIPE --resume ...` (NAME is the runs root: the
#        stages run in $RUNS/NAME/RECIPE/STAGE, a campaign's in training/campaigns/ restored there)
#   tools/device_train.sh seed NAME RUN.tgz            unpack a carried run (e.g. runs/NAME.tgz) into
#        $RUNS so that `start NAME -- ... --resume` continues it
#   tools/device_train.sh wait NAME SECONDS          follow the log until the run ends or SECONDS pass
#   tools/device_train.sh collect NAME               pack the run (no tensorboard) and its log into $OUT
#
# A detached run outlives the device call that started it (the machine keeps it until given back), so
# one run spans several 10-minute calls; `collect` after each call keeps the newest checkpoint safe.
# Runs and logs live OUTSIDE the repository copy: each device call lays the working tree anew and
# deletes files the previous call left in it (a run's metrics.csv and log were lost that way).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
SITE=/tmp/site
RUNS=${T1_DEVICE_RUNS:-/root/t1runs}
export PYTHONPATH=$SITE:$PWD:$PWD/build/gen/python PYTHONUNBUFFERED=1

install_wheels() {
  [[ -f $SITE/.done ]] && return
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target $SITE .whl/*.whl
  touch $SITE/.done
  python3 -c "import jax, mujoco, brax; print('jax', jax.__version__, jax.devices(), 'mujoco', mujoco.__version__)"
}

running() { pgrep -f "python3 -m training (train|recipe|distill)" >/dev/null; }

case "${1:-}" in
  start)
    name=$2; shift 3  # NAME --
    install_wheels
    mkdir -p "$RUNS"
    setsid nohup python3 -m training "$@" --out "$RUNS/$name" >> "$RUNS/$name.log" 2>&1 < /dev/null &
    echo "started $name: python -m training $* --out $RUNS/$name" ;;
  seed)
    mkdir -p "$RUNS"; tar -C "$RUNS" -xzf "$3"; ls "$RUNS/$2" ;;
  wait)
    name=$2; deadline=$((SECONDS + $3))
    sleep 5
    while running && ((SECONDS < deadline)); do sleep 10; done
    tr '\r' '\n' < "$RUNS/$name.log" | grep -v '^\s*$' | tail -n 25
    running && echo "[still running]" || echo "[ended]" ;;
  collect)
    name=$2; out=${OUT:?collect needs \$OUT (a device call)}
    tar -C "$RUNS" --exclude tensorboard -czf "$out/$name.tgz" "$name"
    cp "$RUNS/$name.log" "$out/"; ls -la "$out" ;;
  *)
    echo "usage: $0 start NAME -- train|recipe ARGS... | seed NAME RUN.tgz | wait NAME SECONDS | collect NAME" >&2; exit 2 ;;
esac
