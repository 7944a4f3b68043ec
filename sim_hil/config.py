"""Simulator constants (one place; the CLI overrides some)."""

CONTROL_DT_S = 0.002            # bus cycle = state/command period: the runtime's 500 Hz tick
DEFAULT_PHYSICS_DT_S = 0.002    # MuJoCo step; must divide CONTROL_DT_S
STATUS_RATE_HZ = 10.0           # T1_SIM_STATUS rate (sim time)
LOCKSTEP_TIMEOUT_S = 0.5        # wall time to wait for the command answering state k before going on
LOCKSTEP_FIRST_COMMAND_TIMEOUT_S = 30.0   # the client may still be starting: wait longer for the first one
FALLEN_TRUNK_HEIGHT_M = 0.35    # Trunk origin below this = lying on the ground (standing: 0.665 m)
VIDEO_FPS = 30
VIDEO_SIZE = (480, 640)         # (height, width) [px]
STATS_WINDOW_S = 1.0            # real-time factor averaging window [s of sim time]
