"""Intel RealSense backend (``realsense:<serial>``): the colour sensor of a D400-series camera
as a monocular camera, with the factory intrinsics stored in the device, through
``pyrealsense2`` (the optional extra ``pip install 'armstereo[realsense]'``). A recording made
by the SDK (``.bag``, or ``.db3`` from SDK 2.56 on) plays back through the same code."""
