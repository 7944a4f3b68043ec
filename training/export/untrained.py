"""Write the untrained student placeholder that `make demo` runs while no trained student is shipped:
the student's shape (82 → 512 → 256 → 128 → 2·23, swish, tanh_normal) with seeded random-init weights and
an identity normaliser, manifest `trained: false`, so every report and the demo can say it is untrained.

    python -m training.export.untrained policies/student_untrained/student_untrained.safetensors
"""
from __future__ import annotations

import argparse
import subprocess
from datetime import date

import numpy as np

from common import observation as obsdef
from common.artifact import write_artifact
from common.golden import GOLDEN_HIDDEN, base_manifest, random_policy

SEED = 1


def _git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    args = ap.parse_args(argv)
    layers, _, _ = random_policy(np.random.default_rng(SEED), obsdef.TERMS_UNION, GOLDEN_HIDDEN)
    size = obsdef.observation_size(obsdef.TERMS_UNION)
    manifest = base_manifest(name="student_untrained", trained=False, provenance={
        "git_commit": _git_commit(), "steps": 0, "date": date.today().isoformat(),
        "command": f"python -m training.export.untrained {args.out}  (random init, seed {SEED}: NOT TRAINED)"})
    digest = write_artifact(args.out, layers, np.zeros(size, np.float32), np.ones(size, np.float32), manifest)
    print(f"wrote {args.out} (untrained, content_hash {digest[:12]})")


if __name__ == "__main__":
    main()
