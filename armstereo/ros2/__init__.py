"""ROS 2 in and out: armstereo recordings as ROS 2 bags, and ROS 2 bags as recordings.

- :func:`armstereo.ros2.export.export_recording` writes any armstereo MCAP (capture, scan,
  calibration, reconstruction, fusion, scene) as a rosbag2 bag in MCAP storage with the
  standard message types (``armstereo export REC.mcap --to ros2 --out BAG``);
- :func:`armstereo.ros2.importer.import_bag` turns a ROS 2 bag (MCAP or sqlite3 storage) with
  images, camera info and TF (or joint states) into armstereo recordings
  (``armstereo import BAG --image-topic T --out REC.mcap``).

Both need the optional extra ``armstereo[ros2]`` (the pure-Python ``rosbags`` library; no ROS
installation). Nothing here is imported by the rest of armstereo. See docs/ros2.md.
"""
