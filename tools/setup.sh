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
  chromium                      # headless: Rerun's web viewer as a person sees it (tests/test_rerun_view.py)
  clang-format                  # make lint: the C/C++ style check (.clang-format)
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
# Rerun's usage analytics off for this user before anything of Rerun's runs (sim_hil/rerun_view/analytics.py)
PYTHONPATH=. .venv/bin/python -c 'from sim_hil.rerun_view.analytics import disable_analytics; disable_analytics()'


# The checkout and its generated LCM bindings on the venv's import path, so `.venv/bin/python -m sim_hil …`
# runs from a shell with nothing set by hand. The venv may be shared by several checkouts (a symlinked .venv
# in git worktrees): the .pth takes the checkout the interpreter was started from (the folder holding
# sys.prefix, i.e. CHECKOUT/.venv) and falls back to the one that ran this setup last. Its paths go after
# site-packages, so PYTHONPATH (the Makefile's) still comes first.
site=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
fallback=$(pwd -P)
cat > "$site/t1_checkout.pth" <<PTH
import os, sys; t1_root = next((r for r in (os.path.dirname(sys.prefix), '$fallback') if os.path.isfile(os.path.join(r, 'messages', 'contract.json'))), None); t1_root and sys.path.extend(p for p in (t1_root, os.path.join(t1_root, 'build', 'gen', 'python')) if p not in sys.path)
PTH
echo "setup: ok"
