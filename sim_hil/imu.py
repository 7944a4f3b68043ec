"""The IMU at the Trunk origin (site `imu`): orientation, gyro and accelerometer from MuJoCo sensors,
with the fault layer's noise and bias added, as a real IMU driver would publish them."""
from __future__ import annotations

import mujoco
import numpy as np


def _sensor_slice(model: mujoco.MjModel, sensor_type: int) -> slice:
    site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "imu")
    for s in range(model.nsensor):
        if model.sensor_type[s] == sensor_type and model.sensor_objid[s] == site_id:
            adr = model.sensor_adr[s]
            return slice(adr, adr + model.sensor_dim[s])
    raise ValueError(f"model has no sensor of type {mujoco.mjtSensor(sensor_type).name} on site 'imu'")


class Imu:
    def __init__(self, model: mujoco.MjModel, rng: np.random.Generator):
        self.rng = rng
        self._quat = _sensor_slice(model, mujoco.mjtSensor.mjSENS_FRAMEQUAT)
        self._gyro = _sensor_slice(model, mujoco.mjtSensor.mjSENS_GYRO)
        self._accel = _sensor_slice(model, mujoco.mjtSensor.mjSENS_ACCELEROMETER)

    @property
    def addresses(self) -> tuple[int, int, int]:
        """sensordata addresses of the orientation, gyro and accelerometer readings."""
        return self._quat.start, self._gyro.start, self._accel.start

    def read(self, data: mujoco.MjData, noise: dict, bias: dict):
        """(quat w x y z, gyro [rad/s], accel [m/s²]) with noise (std) and bias applied."""
        quat = data.sensordata[self._quat].copy()
        gyro = data.sensordata[self._gyro] + bias["gyro"]
        accel = data.sensordata[self._accel] + bias["accel"]
        # Draw only when a noise fault is active, so fault-free runs consume no random numbers.
        if noise["gyro"] > 0:
            gyro = gyro + self.rng.normal(0.0, noise["gyro"], 3)
        if noise["accel"] > 0:
            accel = accel + self.rng.normal(0.0, noise["accel"], 3)
        if noise["quat"] > 0:
            quat = quat + self.rng.normal(0.0, noise["quat"], 4)
            quat /= np.linalg.norm(quat)
        return quat, gyro, accel
