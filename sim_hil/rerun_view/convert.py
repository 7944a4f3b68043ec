"""An LCM log → a Rerun recording (.rrd) with the shipped blueprint. The log is read by the project's reader
(sim_hil.lcmlog.eventlog), so a damaged log converts as far as it can be read; each problem it names is also
put into the recording's events, at the log's first time."""
from __future__ import annotations

from pathlib import Path

import rerun as rr

from sim_hil.lcmlog.eventlog import ProjectLog, open_log
from sim_hil.lcmlog.plot import sim_clock
from sim_hil.rerun_view.analytics import disable_analytics
from sim_hil.rerun_view.blueprint import blueprint
from sim_hil.rerun_view.columns import channel_columns
from sim_hil.rerun_view.record import CHANNELS_SHOWN, EVENT_CHANNELS, EVENTS, RunRecorder
from sim_hil.rerun_view.robot import RobotGeoms

APPLICATION_ID = "t1_run"
# the busy channels, decoded a channel at a time (columns.py)
COLUMN_CHANNELS = CHANNELS_SHOWN - set(EVENT_CHANNELS)


def read_for_recording(path) -> tuple[ProjectLog, dict]:
    """The log (its problems named by the project's reader) and the batch to record. The busy channels come
    as columns; if one of them is damaged or of another version, the reader decodes it message by message."""
    log = open_log(path, CHANNELS_SHOWN - COLUMN_CHANNELS)
    batch = {}
    for channel in COLUMN_CHANNELS:
        columns = channel_columns(log.events, channel)
        if columns is None and any(ev.channel == channel for ev in log.events):
            log = open_log(path, CHANNELS_SHOWN)
            return log, _messages(log)
        if columns is not None:
            batch[channel] = columns
    return log, {**_messages(log), **batch}


def _messages(log: ProjectLog) -> dict:
    return {ch: [(ev.timestamp_us, msg) for ev, msg in entries] for ch, entries in log.messages.items()
            if ch in CHANNELS_SHOWN}


def convert(log: ProjectLog, out: Path, with_robot: bool = True, batch: dict | None = None) -> dict[str, int]:
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
    recorder.write(_messages(log) if batch is None else batch)
    rec.flush()
    rec.disconnect()
    return dict(recorder.rows)
