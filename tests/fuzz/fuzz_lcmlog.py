"""atheris harness: an LCM event log as `make replay` and `make plot-log` read it (sim_hil/lcmlog).
Input: the log file's bytes. Path: parse_events (sync words, lengths, corrupt spans, truncation) ->
decode_events (project channels, fingerprints, legacy state upgrade, lcm-gen's decoders) -> the problem
sentences -> the plot's time axis and series. Nothing may raise; every event lies inside the file.

    python -m tests.fuzz.fuzz_lcmlog [libFuzzer flags] [corpus dirs]   (tools/fuzz.py runs it)
"""
import sys
from pathlib import Path

import atheris

with atheris.instrument_imports():
    import t1  # noqa: F401  lcm-gen's Python decoders of every project type (decode_events imports them from here)
    from t1 import (  # noqa: F401
        action_t,
        controller_status_t,
        imu_t,
        joint_command_t,
        joint_state_t,
        joystick_t,
        observation_t,
        run_info_t,
        runtime_cmd_t,
        sim_status_t,
    )

    from messages import contract
    from sim_hil.lcmlog import eventlog
    from sim_hil.lcmlog.plot import series

LOG = Path("fuzz.lcmlog")


def test_one_input(data: bytes) -> None:
    problems = eventlog.LogProblems()
    events = eventlog.parse_events(data, problems)
    for ev in events:
        assert 0 <= ev.offset and ev.offset + eventlog.HEADER.size + len(ev.data) <= len(data), ev
    for start, end in problems.corrupt_spans:
        assert 0 <= start < end <= len(data), (start, end)
    decoded = eventlog.decode_events(events, problems)
    problems.messages(LOG)
    if events:
        log = eventlog.ProjectLog(LOG, events, decoded, problems)
        series(log, contract.CH_JOINT_STATE, "utime", "seq")
        series(log, contract.CH_IMU, "utime")


def main() -> None:
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
