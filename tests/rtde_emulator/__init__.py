"""An emulated UR controller for integration tests of the real ur_rtde client.

It serves RTDE (30004), the dashboard server (29999) and the script port (30003) on a loopback
address of its own, in a separate process, and plays ur_rtde's control-script register
protocol instead of running URScript. Modules: ``protocol`` (RTDE wire format), ``rtde_server``
(sessions and the controller clock), ``servers`` (ports, dashboard, script upload),
``controller`` (arm state, modes, program life cycle, faults), ``script`` (the register
protocol), ``motion`` (moveJ/moveL trajectories), ``faults`` (fault switches),
``primary_server`` (the read-only primary/secondary state stream), ``harness``
(starting and steering it from a test). Run it from the repository root with
``python -m tests.rtde_emulator --help``.

By default the emulated arm carries a factory calibration (``DEFAULT_KINEMATICS``, a seeded
synthetic one), like every real arm: its motion and reported poses follow that table, and it
broadcasts it on the primary stream. ``--kinematics nominal`` gives URSim's exact nominal arm.
"""

DEFAULT_CALIBRATION_SEED = 1
DEFAULT_KINEMATICS = f"calibrated:{DEFAULT_CALIBRATION_SEED}"
