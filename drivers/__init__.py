"""Arm and camera backends behind one interface each (see :mod:`armstereo.devices`).

Registry names used by the CLI: arms ``mock`` and ``ur``; cameras ``mock`` and
``opencv:<index-or-path>``. Vendor SDKs are imported only inside the backend that needs them.
"""
