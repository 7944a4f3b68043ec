"""A recipe's keyframe chain ships as one folder (training/export/brax.ship_chain): each member under its own
name, a provenance row each in the folder's card, and the chain's manifest, which the evaluations load."""
import json

from common import events, keyframe_chain
from common.artifact import read_artifact, write_artifact
from training.evaluation.artifact_policy import ChainPolicy, load_policy
from training.export.brax import ship_chain

BASELINE = "policies/getup_baseline/getup_baseline.safetensors"


def _member(tmp_path, role):
    layers, mean, std, manifest = read_artifact(BASELINE)
    manifest = {**manifest, "name": f"getup_keyframe_{role}",
                "provenance": {**manifest["provenance"], "command": f"recipe stage {role}"}}
    path = tmp_path / "runs" / f"{role}.safetensors"
    path.parent.mkdir(exist_ok=True)
    write_artifact(path, layers, mean, std, manifest)
    return path


def test_a_shipped_chain_is_a_folder_of_its_members_and_their_manifest(tmp_path):
    members = {role: _member(tmp_path, role) for role in events.KEYFRAME_STAGES}
    folder = ship_chain("getup_keyframe", members, "kneel_band", {"task": "recipe getup_keyframe"},
                        policies_root=tmp_path / "policies")
    assert folder == tmp_path / "policies" / "getup_keyframe"
    chain = keyframe_chain.read(folder)
    assert [p.name for p in chain.members] == [f"getup_keyframe_{r}.safetensors" for r in events.KEYFRAME_STAGES]
    assert json.loads((folder / keyframe_chain.MANIFEST).read_text())["handover"] == "kneel_band"
    card = (folder / "CARD.md").read_text()
    assert all(f"recipe stage {role}" in card for role in events.KEYFRAME_STAGES)   # a provenance row each
    policy = load_policy(folder)
    assert isinstance(policy, ChainPolicy) and policy.handover_up_error == events.KNEEL_BAND_UP_ERROR
