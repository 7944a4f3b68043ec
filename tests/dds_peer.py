"""Plays the DDS robot (or watches it) from a test, with cyclonedds-python inside tools/netns: writes
LowState_ on rt/low_state, reads LowCmd_ from rt/joint_ctrl. Types from messages/dds_types.py."""
from __future__ import annotations

import time

import numpy as np
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from messages import contract, dds_types
from sim_hil.dds_bridge import dds_qos

N = contract.NUM_JOINTS


def low_state(q, rpy=(0.0, 0.0, 0.0), n_motors: int = N, dq=None):
    """A LowState_ with n_motors serial entries (q and dq cycled over the 23 given values)."""
    dq = np.zeros(N) if dq is None else dq
    motors = [dds_types.MotorState(mode=0, q=float(q[i % N]), dq=float(dq[i % N]), ddq=0.0, tau_est=0.0,
                                   temperature=0, lost=0, reserve=[0, 0]) for i in range(n_motors)]
    imu = dds_types.ImuState(rpy=[float(v) for v in rpy], gyro=[0.0] * 3, acc=[0.0, 0.0, 9.81])
    return dds_types.LowState(imu_state=imu, motor_state_parallel=[], motor_state_serial=motors)


class DdsRobotPeer:
    def __init__(self, write_state: bool = True, read_commands: bool = True):
        self.participant = DomainParticipant(contract.DDS["domain_id"])
        self.writer = self.reader = None
        if write_state:
            topic = Topic(self.participant, contract.DDS["state_topic"], dds_types.LowState)
            self.writer = DataWriter(self.participant, topic, qos=dds_qos(reliable=True))
        if read_commands:
            topic = Topic(self.participant, contract.DDS["command_topic"], dds_types.LowCmd)
            self.reader = DataReader(self.participant, topic, qos=dds_qos(reliable=False))
        self.cmds: list = []

    def take(self) -> list:
        got = list(self.reader.take(N=256))
        self.cmds.extend(got)
        return got

    def wait_cmds(self, until, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while not until():
            if time.monotonic() > deadline:
                return False
            self.take()
            time.sleep(0.005)
        return True

    def write(self, sample) -> None:
        self.writer.write(sample)
