"""Runs in Rerun (sim_hil/rerun_view): the recording of a short demo run read back (its entities, one sample
per logged message, time going forward), the robot drawn in the web viewer in headless Chromium against the
empty scene, a damaged log converted as far as it can be read with the rest named, and the live bridge
streaming the same entities from the LCM group."""
from __future__ import annotations

import struct
import subprocess
import sys
from collections import defaultdict

import numpy as np
import pyarrow as pa
import pytest
import rerun.chunk as rrc

from messages import contract
from sim_hil.launch import ROOT, _env
from sim_hil.lcmlog.eventlog import Event, LogProblems, open_log, read_events, write_events
from sim_hil.rerun_view.analytics import analytics_disabled
from sim_hil.rerun_view.record import EVENTS, SERIES, TIMELINE, joint_entity
from sim_hil.rerun_view.robot import RobotGeoms
from tests import rerun_web

JOYSTICK_EXPERT = ROOT / "policies" / "joystick" / "joystick.safetensors"
RUN_S = 3.0                    # the demo run's sim seconds
VIEW_TIMEOUT_S = 240.0         # the web viewer on SwiftShader, on two loaded cores
LIVE_SIM_S = 2.0


def _run(*args, timeout=180):
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=_env(), capture_output=True, text=True,
                          timeout=timeout)


def read_back(rrd):
    """entity -> (rows, {timeline: times in file order}) of the temporal data; and the blueprint stores."""
    reader = rrc.RrdReader(rrd)
    rows, times = defaultdict(int), defaultdict(lambda: defaultdict(list))
    for chunk in reader.store().stream():
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        rows[chunk.entity_path] += chunk.num_rows
        for timeline in chunk.timeline_names:
            col = batch.column(batch.schema.get_field_index(timeline))
            times[chunk.entity_path][timeline].extend(col.cast(pa.int64()).to_pylist())
    return rows, times, reader.blueprints()


@pytest.fixture(scope="module")
def demo_log(tmp_path_factory, netns):
    out = tmp_path_factory.mktemp("demo")
    run = _run("-m", "sim_hil.demo", "--policy", str(JOYSTICK_EXPERT), "--spawn", "standing", "--seconds", str(RUN_S),
               "--out", str(out))
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    return out / "demo.lcmlog"


@pytest.fixture(scope="module")
def demo_rrd(demo_log):
    rrd = demo_log.with_suffix(".rrd")
    done = _run("-m", "sim_hil.lcmlog", "rerun", str(demo_log), "-o", str(rrd))
    assert done.returncode == 0, done.stderr
    assert analytics_disabled()                     # Rerun was told before it ran
    return rrd


def test_recording_holds_every_logged_message_in_time_order(demo_log, demo_rrd):
    log = open_log(demo_log)
    count = {ch: len(entries) for ch, entries in log.messages.items()}
    for ch in (contract.CH_JOINT_STATE, contract.CH_JOINT_CMD, contract.CH_JOYSTICK, contract.CH_SIM_STATUS,
               contract.CH_CONTROLLER_STATUS, contract.CH_IMU):
        assert count.get(ch, 0) > 0, f"the demo logged no {ch}"
    rows, times, blueprints = read_back(demo_rrd)
    assert blueprints, "no blueprint shipped with the recording"
    expected = {path: count[channel] for path, (channel, _, _) in SERIES.items()}
    for name in contract.JOINT_NAMES:
        expected[joint_entity(name, "q")] = expected[joint_entity(name, "tau_est")] = count[contract.CH_JOINT_STATE]
        expected[joint_entity(name, "q_des")] = count[contract.CH_JOINT_CMD]
    for k in range(len(RobotGeoms().ids)):
        expected[RobotGeoms().entity(k)] = count[contract.CH_JOINT_STATE]
    got = {path: rows.get("/" + path, 0) for path in expected}
    assert got == expected
    assert rows["/" + EVENTS] >= 2                  # the run_info stamps and the runtime's first mode at least
    for path in list(expected) + [EVENTS]:
        for timeline, stamps in times["/" + path].items():
            assert np.all(np.diff(stamps) >= 0), f"{path}: {timeline} goes back"
        assert set(times["/" + path]) == {TIMELINE, "sim_time"}


def test_web_viewer_draws_the_robot(demo_log, demo_rrd, tmp_path):
    """What a person sees: the recording in Rerun's web viewer, in headless Chromium; the 3-D view differs from
    the same recording without the robot (its plots drawn) in a robot-sized share of its pixels."""
    from sim_hil.rerun_view.convert import convert
    empty = convert(open_log(demo_log), tmp_path / "empty.rrd", with_robot=False) and tmp_path / "empty.rrd"
    empty_img, robot_img, (empty_png, png), share = rerun_web.robot_screenshot(demo_rrd, empty, VIEW_TIMEOUT_S)
    (tmp_path / "empty.png").write_bytes(empty_png)
    (tmp_path / "robot.png").write_bytes(png)
    assert rerun_web.loaded(empty_img) and rerun_web.loaded(robot_img)
    assert share > rerun_web.ROBOT_MIN_SHARE
    # where the robot changed the 3-D view, it is the geoms' grey (R ≈ G, no saturated colour): drawn, not a dialog
    view, base = rerun_web.view_3d(robot_img), rerun_web.view_3d(empty_img)
    changed = np.abs(view - base).max(axis=-1) > rerun_web.PIXEL_DIFF
    assert np.median(view[changed].max(axis=-1) - view[changed].min(axis=-1)) < 0.15


def _damaged(log_path, out):
    """The demo's log with T1_JOINT_CMD of another type version and its last event cut in half."""
    events = read_events(log_path, LogProblems())
    other = [Event(e.offset, e.timestamp_us, e.channel,
                   struct.pack(">Q", 0x1234_5678_9ABC_DEF0) + e.data[8:] if e.channel == contract.CH_JOINT_CMD
                   else e.data)
             for e in events]
    write_events(out, other)
    with open(out, "r+b") as f:
        f.truncate(out.stat().st_size - len(events[-1].data) // 2 - 1)
    return out


def test_damaged_log_converts_what_it_can_and_names_the_rest(demo_log, tmp_path):
    damaged = _damaged(demo_log, tmp_path / "damaged.lcmlog")
    done = _run("-m", "sim_hil.lcmlog", "rerun", str(damaged), "-o", str(tmp_path / "damaged.rrd"))
    assert done.returncode == 0, done.stderr
    assert "truncated" in done.stderr and "T1_JOINT_CMD" in done.stderr and "another" in done.stderr
    log = open_log(damaged)
    rows, _, _ = read_back(tmp_path / "damaged.rrd")
    assert rows["/" + joint_entity("Left_Knee_Pitch", "q")] == len(log.messages[contract.CH_JOINT_STATE])
    assert "/" + joint_entity("Left_Knee_Pitch", "q_des") not in rows
    texts = [t for chunk in rrc.RrdReader(tmp_path / "damaged.rrd").store().stream()
             if chunk.entity_path == "/" + EVENTS and not chunk.is_static
             for t in chunk.to_record_batch().column("TextLog:text").to_pylist()]
    assert any("truncated" in str(t) for t in texts) and any("T1_JOINT_CMD" in str(t) for t in texts)


def test_bad_arguments_are_one_line_errors(tmp_path):
    missing = _run("-m", "sim_hil.lcmlog", "rerun", str(tmp_path / "nope.lcmlog"))
    assert missing.returncode == 2 and "no such log file" in missing.stderr and "Traceback" not in missing.stderr


def test_live_bridge_streams_the_runs_entities(tmp_path, netns):
    """The bridge beside a running simulator writes the same entities as a converted log; it starts before the
    simulator and is stopped by SIGTERM, flushing what it holds."""
    rrd = tmp_path / "live.rrd"
    bridge = subprocess.Popen([sys.executable, "-m", "sim_hil.rerun_view.live", "--save", str(rrd)], cwd=ROOT,
                              env=_env(), stderr=subprocess.PIPE, text=True)
    try:
        assert "subscribed" in bridge.stderr.readline()
        sim = _run("-m", "sim_hil", "--quiet", "--no-log", "--spawn", "standing", "--clock", "realtime",
                   "--duration", str(LIVE_SIM_S))
        assert sim.returncode == 0, sim.stderr[-2000:]
    finally:
        bridge.terminate()
        _, err = bridge.communicate(timeout=60)
    assert bridge.returncode == 0, err
    rows, times, blueprints = read_back(rrd)
    assert blueprints
    states = rows["/" + joint_entity("Left_Knee_Pitch", "q")]
    assert states > 0 and rows["/robot/geoms/trunk"] == states and rows["/trunk/height"] > 0
    assert np.all(np.diff(times["/robot/geoms/trunk"][TIMELINE]) >= 0)


def test_rerun_live_serves_the_run_on_loopback_only(tmp_path, netns):
    """tools/rerun_live (make demo|teleop|sim VIEW=rerun): while the run goes, the web viewer answers on
    127.0.0.1 and nothing of Rerun's listens on another address; the wrapper ends with the run (no terminal)."""
    import time
    import urllib.request
    web, grpc = rerun_web.free_port(), rerun_web.free_port()
    env = dict(_env(), RERUN_WEB_PORT=str(web), RERUN_GRPC_PORT=str(grpc))
    live = subprocess.Popen([str(ROOT / "tools" / "rerun_live"), sys.executable, "-m", "sim_hil", "--quiet", "--no-log",
                             "--spawn", "standing", "--clock", "realtime", "--duration", "20"], cwd=ROOT, env=env,
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                page = urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=2).read()
                break
            except OSError:
                assert live.poll() is None and time.monotonic() < deadline, live.communicate()[1][-2000:]
                time.sleep(0.2)
        assert page
        listening = subprocess.run(["ss", "-ltnH"], capture_output=True, text=True).stdout
        ours = [line.split()[3] for line in listening.splitlines() if line.split()[3].endswith((f":{web}", f":{grpc}"))]
        assert ours and all(addr.startswith("127.0.0.1:") for addr in ours), listening
    finally:
        _, err = live.communicate(timeout=180)
    assert live.returncode == 0, err[-2000:]
    assert f"http://127.0.0.1:{web}/" in err


def test_a_log_without_simulator_status_says_the_pose_is_the_imus(demo_log, tmp_path):
    """A real robot's log has no T1_SIM_STATUS: the robot is still drawn for every state, upright at the
    standing height, oriented by the IMU, and the trunk's label says where its pose comes from."""
    from sim_hil.rerun_view.robot import POSE_FROM_IMU
    robot_log = write_events(tmp_path / "robot.lcmlog", [ev for ev in read_events(demo_log, LogProblems())
                                                         if ev.channel != contract.CH_SIM_STATUS])
    done = _run("-m", "sim_hil.lcmlog", "rerun", str(robot_log), "-o", str(tmp_path / "robot.rrd"))
    assert done.returncode == 0, done.stderr
    rows, _, _ = read_back(tmp_path / "robot.rrd")
    assert rows["/robot/geoms/trunk"] == len(open_log(robot_log).messages[contract.CH_JOINT_STATE])
    labels = [label for chunk in rrc.RrdReader(tmp_path / "robot.rrd").store().stream()
              if chunk.entity_path == "/robot/geoms/trunk" and chunk.is_static
              for name in chunk.to_record_batch().schema.names if name.endswith(":labels")
              for label in chunk.to_record_batch().column(name).to_pylist()]
    assert [POSE_FROM_IMU] in labels, labels
