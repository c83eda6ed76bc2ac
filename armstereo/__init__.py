"""armstereo: a robot arm with a wrist camera as a 3D scanner.

The arm moves its one camera by a commanded baseline; forward kinematics of the actual joints
gives each view's pose; the pair is rectified (Fusiello), matched (Birchfield-Tomasi) and
triangulated into a point cloud in the robot's ``base`` frame.
"""

__version__ = "0.1.0"
