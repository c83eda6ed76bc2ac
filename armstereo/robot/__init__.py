"""A UR arm's kinematics, all in one place.

* :mod:`~armstereo.robot.arm_model`: :class:`ArmModel`, FK, the flange Jacobian, IK and joint
  limits in the controller's ``base`` frame (Pinocchio underneath).
* :mod:`~armstereo.robot.dh`: UR's nominal Denavit-Hartenberg tables and the calibrated table a
  controller reports; FK by composing DH matrices; hashes.
* :mod:`~armstereo.robot.pinocchio_dh`: the Pinocchio model built from a table.
* :mod:`~armstereo.robot.model_file`: the file a calibrated model is saved in for offline use.
* :mod:`~armstereo.robot.source`: which kinematics a capture uses (controller, file, nominal)
  and how a recording says so.
* :mod:`~armstereo.robot.synthetic`: seeded factory calibrations for simulated arms.

Nothing here talks to an arm; ``drivers.ur.primary`` reads the controller's table.
``armstereo.kinematics`` still hands on :class:`ArmModel` and its constants for old scripts.
"""
