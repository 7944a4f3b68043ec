"""Each shared constant has one definition: the loop and policy rates, the heights (fallen, standing, the
kneel gate, the waist switch, the getup reward's standing targets) and the joint ranges live in
messages/contract.json, and the Python packages read them through messages/contract.py (C and C++ through the
headers generated from it). This scans the packages' sources (their AST) for a
second definition: a name or config key that speaks of one of these quantities given one of their values as
a literal, and the names retired because they meant different things in different modules."""
from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import numpy as np
import pytest

from messages import contract

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("messages", "common", "sim_hil", "training")
DATA = json.loads((ROOT / "messages" / "contract.json").read_text())

RATE_VALUES = {contract.LOOP_PERIOD_S, contract.POLICY_PERIOD_S, contract.LOOP_RATE_HZ, contract.POLICY_RATE_HZ}
HEIGHT_VALUES = {contract.FALLEN_TRUNK_HEIGHT_M, contract.STANDING_TRUNK_THRESHOLD_M,
                 contract.NOMINAL_STANDING_TRUNK_HEIGHT_M, contract.STANDING_TARGET_TRUNK_M,
                 contract.STANDING_TARGET_WAIST_M, contract.KNEEL_GATE_HEIGHT_M, contract.WAIST_SWITCH_HEIGHT_M}
# a name (variable, attribute, keyword, dict key) that speaks of the loop's or the policy's rate ...
RATE_NAME = re.compile(r"ctrl_dt|control_dt|loop_(dt|period)|policy_(dt|period|rate|hz)|tick_s\b|decimation|"
                       r"sim_dt|physics_dt", re.I)
# ... or of a body height
HEIGHT_NAME = re.compile(r"height|standing|fallen|fall_trunk|gate|switch", re.I)
# (file relative to the root, name): literals under such names that mean something else, with the reason
ALLOWED: dict[tuple[str, str], str] = {}
RETIRED_NAMES = {
    "CONTROL_DT_S": "meant 0.02 s in one module and 0.002 s in another: contract.POLICY_PERIOD_S / LOOP_PERIOD_S",
    "STANDING_TRUNK_HEIGHT_M": "the standing threshold: contract.STANDING_TRUNK_THRESHOLD_M",
    "STANDING_TORSO_M": "the getup reward's target: contract.STANDING_TARGET_TRUNK_M",
    "STANDING_WAIST_M": "the getup reward's target: contract.STANDING_TARGET_WAIST_M",
    "GATE_HEIGHT_M": "the kneel gate's height: events.KNEEL_GATE_HEIGHT_M (= contract.KNEEL_GATE_HEIGHT_M)",
}


def _sources() -> list[Path]:
    return sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))


def _number(node: ast.AST) -> float | None:
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        inner = _number(node.operand)
        return None if inner is None else -inner
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return float(node.value)
    return None


def _named_literals(tree: ast.AST):
    """(line, name, value) of every number given to a name: assignments, keyword arguments, dict entries."""
    for node in ast.walk(tree):
        pairs = []
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            pairs = [(t, node.value) for t in targets if node.value is not None]
        elif isinstance(node, ast.keyword) and node.arg:
            pairs = [(node.arg, node.value)]
        elif isinstance(node, ast.Dict):
            pairs = [(k.value, v) for k, v in zip(node.keys, node.values)
                     if isinstance(k, ast.Constant) and isinstance(k.value, str)]
        for target, value in pairs:
            name = target if isinstance(target, str) else getattr(target, "id", None) or getattr(target, "attr", None)
            number = _number(value)
            if name and number is not None:
                yield getattr(value, "lineno", 0), name, number


def _matches(number: float, values: set[float]) -> bool:
    return any(abs(number - v) < 1e-12 for v in values)


def test_contract_defines_each_shared_constant():
    for key in ("loop_period_s", "policy_decimation", "fallen_trunk_height_m", "standing_trunk_threshold_m",
                "nominal_standing_trunk_height_m", "standing_target_trunk_m", "standing_target_waist_m",
                "kneel_gate_height_m", "waist_switch_height_m"):
        assert key in DATA, f"messages/contract.json: no {key}"
    assert contract.POLICY_PERIOD_S == pytest.approx(contract.LOOP_PERIOD_S * contract.POLICY_DECIMATION)


def test_no_second_definition_in_the_python_sources():
    found = []
    for path in _sources():
        rel = path.relative_to(ROOT).as_posix()
        if rel == "messages/contract.py":
            continue
        tree = ast.parse(path.read_text())
        for line, name, number in _named_literals(tree):
            if (rel, name) in ALLOWED:   # a literal that means something else (ALLOWED says what)
                continue
            if RATE_NAME.search(name) and (_matches(number, RATE_VALUES) or "decimation" in name.lower()):
                found.append(f"{rel}:{line}: {name} = {number:g} (a rate: messages/contract.py)")
            elif HEIGHT_NAME.search(name) and _matches(number, HEIGHT_VALUES):
                found.append(f"{rel}:{line}: {name} = {number:g} (a height: messages/contract.py)")
    assert not found, "constants defined again outside messages/contract.json:\n" + "\n".join(found)


def test_retired_names_are_gone():
    found = []
    for path in _sources():
        for node in ast.walk(ast.parse(path.read_text())):
            name = getattr(node, "id", None) or getattr(node, "attr", None)
            if name in RETIRED_NAMES:
                found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {name}: {RETIRED_NAMES[name]}")
    assert not found, "\n".join(found)


def test_the_scan_finds_a_second_definition():
    """The scan itself: a module repeating the fallen height, the policy period or the decimation is caught."""
    tree = ast.parse("FALLEN_TRUNK_HEIGHT_M = 0.35\ncfg = dict(ctrl_dt=0.02)\nPOLICY_DECIMATION = 10\n"
                     "x = {'fall_trunk_height_m': 0.35}\nOTHER = 0.35\n")
    hits = [(name, number) for _, name, number in _named_literals(tree)
            if (HEIGHT_NAME.search(name) and _matches(number, HEIGHT_VALUES))
            or (RATE_NAME.search(name) and (_matches(number, RATE_VALUES) or "decimation" in name.lower()))]
    assert sorted(hits) == sorted([("FALLEN_TRUNK_HEIGHT_M", 0.35), ("ctrl_dt", 0.02), ("POLICY_DECIMATION", 10.0),
                                   ("fall_trunk_height_m", 0.35)])


def test_the_runtime_reads_its_rates_from_the_contract():
    """The runtime's loop constants (runtime/include/t1rt/constants.hpp) are the generated contract's, not a copy."""
    header = (ROOT / "runtime" / "include" / "t1rt" / "constants.hpp").read_text()
    assert '#include "t1_contract.hpp"' in header
    for name, source in (("kLoopDtS", "t1::kLoopPeriodS"), ("kPolicyDecimation", "t1::kPolicyDecimation")):
        assert re.search(rf"constexpr\s+\w+\s+{name}\s*=\s*{re.escape(source)}\s*;", header), f"{name} is not {source}"


def test_the_joint_ranges_have_one_source():
    """The joint ranges live in contract.json only: t1.xml's joints carry no range (common/model.py applies the
    contract's), and every row of the firmware's motor table names the generated header's bounds, no literal."""
    xml = (ROOT / "common" / "models" / "t1.xml").read_text()
    assert not re.findall(r"<joint\b[^>]*\brange=", xml), "t1.xml: a joint range written again (contract.json has them)"
    header = (ROOT / "firmware_like" / "include" / "t1_motor_protocol.h").read_text()
    table = header[header.index("#define T1_MOTOR_TABLE(X)"):header.index("extern const t1_motor_info_t")]
    rows = re.findall(r'X\(\d+, "(\w+)", \w+, [0-9.]+f,\s*\\?\s*(\w+), (\w+),', table)
    assert [r[0] for r in rows] == list(contract.JOINT_NAMES)
    assert all(lo == f"T1_Q_MIN_RAD_{n}" and hi == f"T1_Q_MAX_RAD_{n}" for n, lo, hi in rows), rows


def test_the_model_and_the_motors_take_the_contracts_ranges():
    from common import model as t1model
    from sim_hil import firmware as fw
    ranges = np.asarray(contract.JOINT_RANGES_RAD)
    model = t1model.load_model()
    np.testing.assert_array_equal(t1model.joint_ranges(model), ranges)
    assert model.jnt_limited[1:].all()
    np.testing.assert_array_equal(fw.Q_MIN, ranges[:, 0].astype(np.float32))
    np.testing.assert_array_equal(fw.Q_MAX, ranges[:, 1].astype(np.float32))
