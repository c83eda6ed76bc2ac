"""Universal Robots backend (CB3 and e-Series) through ur_rtde.

ur_rtde itself is imported only when :meth:`URArm.connect` runs, so importing this package
needs no vendor SDK.
"""

from drivers.ur.arm import URArm

__all__ = ["URArm"]
