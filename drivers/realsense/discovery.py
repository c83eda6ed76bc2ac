"""What ``armstereo cameras`` shows of the RealSense cameras connected (and of a recording
given with ``--realsense-playback``): serial, model, firmware, USB link and colour modes."""

from __future__ import annotations

from drivers.realsense import sdk
from drivers.realsense import settings as S


def list_cameras(options: dict) -> list[dict]:
    """One entry per connected camera, plus the recording ``options["playback"]`` if given."""
    rs = sdk.rs()
    ctx = rs.context()
    devices = [(d, "") for d in ctx.query_devices()]
    if options.get("playback"):
        try:
            devices.append((ctx.load_device(str(options["playback"])),
                            f"recording {options['playback']}"))
        except RuntimeError as err:
            devices.append((None, f"recording {options['playback']}: {sdk.error_text(err)}"))
    return [_entry(rs, d, note) for d, note in devices]


def _entry(rs, device, note: str) -> dict:
    if device is None:
        return {"spec": "", "serial": "", "model": "", "status": "unreadable", "modes": [],
                "note": note}
    info = S.device_info(rs, device)
    modes = sorted({S.mode_of(rs, p).label() for s in device.query_sensors()
                    for p in S.colour_profiles(rs, s)},
                   key=lambda t: [int(x) for x in t.split()[0].replace("@", "x").split("x")])
    usb = info.get("usb", "")
    return {"spec": f"realsense:{info.get('serial', '')}", "serial": info.get("serial", ""),
            "model": info.get("name", ""), "firmware": info.get("firmware", ""),
            "status": "ready", "modes": modes,
            "note": "; ".join(x for x in (note, f"USB {usb}" if usb else "") if x)}
