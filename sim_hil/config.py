"""Simulator constants (one place; the CLI overrides some)."""
from pathlib import Path

from messages import contract

# bus cycle = state/command period [s]: the runtime's loop tick (500 Hz, messages/contract.json)
LOOP_PERIOD_S = contract.LOOP_PERIOD_S
DEFAULT_PHYSICS_DT_S = LOOP_PERIOD_S   # MuJoCo step [s]: one per loop tick unless --physics-dt divides it finer
STATUS_RATE_HZ = 10.0           # T1_SIM_STATUS rate (sim time)
LOCKSTEP_TIMEOUT_S = 0.5        # wall time to wait for the command answering state k before going on
LOCKSTEP_FIRST_COMMAND_TIMEOUT_S = 30.0   # the client may still be starting: wait longer for the first one
# A lockstep sim still without its first command says so after WAIT_NOTICE_FIRST_S, then every WAIT_NOTICE_PERIOD_S [s]
WAIT_NOTICE_FIRST_S = 2.0
WAIT_NOTICE_PERIOD_S = 10.0
# a batch of lockstep ticks in one C++ call ends this far [s] before the next fault edge at the latest, so
# sim time's float rounding never puts the edge's own tick in it
FAULT_EDGE_MARGIN_S = 1e-9
# realtime clock: the last stretch before a tick's deadline is spent polling in a busy loop; a sleep that
# long wakes late by its timer slack plus the scheduler's wake-up latency [s]
REALTIME_SPIN_S = 0.0003
RT_FIFO_PRIORITY = 70           # --rt: SCHED_FIFO priority of the realtime sim (below the runtime's 80)
VIDEO_FPS = 20
GL_PROBE_SIZE_PX = 16          # --record checks the GL backend with a renderer this small at start-up
VIDEO_SIZE = (360, 480)         # (height, width) [px]; software GL renders ~0.1 s per frame here
CAPTION_MARGIN_PX = 4           # the video caption's inset from the frame's corner [px]
CAPTION_WRAP_CHARS = 76         # caption lines wrap here: PIL's default font is 6 px a character
STATS_WINDOW_S = 1.0            # real-time factor averaging window [s of sim time]
SIM_LOG_DIR = Path(__file__).resolve().parents[1] / "out" / "sim"   # `python -m sim_hil`'s default LCM logs
