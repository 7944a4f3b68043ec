#!/usr/bin/env bash
# Idempotent machine + project set-up: Debian packages (only those missing) and the project venv
# (.venv, pinned by requirements.txt; re-installed only when requirements.txt changes).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

APT_PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev nlohmann-json3-dev libgtest-dev libglib2.0-dev libssl-dev
  default-jdk-headless            # javac for the lcm-spy type jar; java for lcm-spy
  iproute2 util-linux             # ip, unshare: the project network namespace (tools/netns)
  libosmesa6 libgl1 xvfb ffmpeg   # offscreen MuJoCo rendering for videos; headless lcm-spy check
  rt-tests                        # cyclictest, the loop-lateness reference in make bench
  cyclonedds-dev cyclonedds-tools # Cyclone DDS 0.10 C API + idlc (t1-runtime --transport dds), ddsperf
  python3-venv
  linux-libc-dev python3-dev    # evdev (sim_hil.teleop) builds its C extension from source
  clang-14 libclang-rt-14-dev   # make test-sanitize / make fuzz: ASan + UBSan, libFuzzer (build-asan)
)

missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing Debian packages: ${missing[*]}"
  SUDO=""; [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

PY=${PYTHON:-python3}
stamp=.venv/.requirements.sha
want=$(sha256sum requirements.txt | cut -d' ' -f1)
if [[ ! -x .venv/bin/python || ! -f $stamp || "$(cat $stamp)" != "$want" ]]; then
  echo "setup: creating/updating .venv from requirements.txt"
  [[ -x .venv/bin/python ]] || "$PY" -m venv .venv
  .venv/bin/pip install -q --upgrade pip
  .venv/bin/pip install -q -r requirements.txt
  echo "$want" > $stamp
fi
echo "setup: ok"
