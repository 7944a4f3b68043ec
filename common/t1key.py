"""`tools/t1key`: messages/auth.py's key tools, with approve refusing any file that is not a valid policy
artifact (the artifact format is this layer's, so the check is handed down from here)."""
from __future__ import annotations

from common.artifact import artifact_problem
from messages import auth

if __name__ == "__main__":
    raise SystemExit(auth.main(artifact_problem=artifact_problem))
