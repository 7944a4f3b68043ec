"""An LCM log → a Rerun recording (.rrd) with the shipped blueprint. The log is read by the project's reader
(sim_hil.lcmlog.eventlog), so a damaged log converts as far as it can be read; each problem it names is also
put into the recording's events, at the log's first time."""
from __future__ import annotations

from pathlib import Path

import rerun as rr

from messages import contract
from sim_hil.lcmlog.eventlog import ProjectLog
from sim_hil.lcmlog.plot import sim_clock
from sim_hil.rerun_view.analytics import disable_analytics
from sim_hil.rerun_view.blueprint import blueprint
from sim_hil.rerun_view.record import EVENTS, RunRecorder
from sim_hil.rerun_view.robot import RobotGeoms

APPLICATION_ID = "t1_run"


def convert(log: ProjectLog, out: Path, with_robot: bool = True) -> dict[str, int]:
    """Write `out`; returns rows per entity (robot/geoms: poses per geom). with_robot=False leaves the 3-D robot
    out (the empty scene a picture of the view is compared with)."""
    disable_analytics()
    out.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream(APPLICATION_ID, send_properties=False)
    rec.save(out, default_blueprint=blueprint())
    rec.send_recording_name(log.path.name)
    recorder = RunRecorder(rec, RobotGeoms() if with_robot else None, sim_clock(log))
    problems = log.problems.messages(log.path)
    if problems:
        rec.send_columns(EVENTS, indexes=recorder.times([log.events[0].timestamp_us] * len(problems)),
                         columns=rr.TextLog.columns(text=[f"log: {p}" for p in problems],
                                                    level=["WARN"] * len(problems)))
        recorder.rows[EVENTS] += len(problems)
    recorder.write({ch: [(ev.timestamp_us, msg) for ev, msg in entries] for ch, entries in log.messages.items()
                    if ch in contract.CHANNELS.values()})
    rec.flush()
    rec.disconnect()
    return dict(recorder.rows)
