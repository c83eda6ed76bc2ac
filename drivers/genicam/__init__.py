"""GenICam camera backend (``genicam:<serial or index>``): GigE Vision and USB3 Vision cameras
through ``harvesters`` and the camera vendor's GenTL producer. The optional extra
``pip install 'armstereo[genicam]'`` installs harvesters; nothing here imports it until a
camera is opened or listed."""
