"""What ``armstereo cameras`` shows of the cameras OpenCV can open: on Linux, the V4L2 video
devices the kernel lists (``/sys/class/video4linux``), by path and name, without opening
them (opening a camera another program streams from can disturb it)."""

from __future__ import annotations

from pathlib import Path

SYSFS = Path("/sys/class/video4linux")


def list_cameras(options: dict) -> list[dict]:
    """One entry per V4L2 capture node; empty where the system has none (or is not Linux)."""
    out = []
    for node in sorted(SYSFS.glob("video*"), key=lambda p: int(p.name[5:] or 0)):
        name_file = node / "name"
        name = name_file.read_text().strip() if name_file.is_file() else ""
        index = (node / "index").read_text().strip() if (node / "index").is_file() else "0"
        if index != "0":  # a device's second node carries metadata, not images
            continue
        out.append({"spec": f"opencv:/dev/{node.name}", "serial": "", "model": name,
                    "status": "present", "modes": [], "note": "modes: ask with --resolution"})
    return out
