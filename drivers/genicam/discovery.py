"""What ``armstereo cameras`` shows of the GenICam cameras a GenTL producer sees: serial,
vendor, model, whether it is free, and (opening each free one briefly) its sizes and pixel
formats."""

from __future__ import annotations

from drivers.genicam import features as F
from drivers.genicam import pixels, producer


def list_cameras(options: dict) -> list[dict]:
    """One entry per camera of the producers given by ``options["cti"]`` (or
    ``GENICAM_GENTL64_PATH``); ConfigError when there is no producer or harvesters."""
    files = producer.producer_files(options.get("cti"))
    h = producer.acquire(files)
    try:
        return [_entry(h, e, files) for e in producer.devices(h)]
    finally:
        producer.release(files)


def _entry(h, e: producer.DeviceEntry, files: tuple[str, ...]) -> dict:
    out = {"spec": f"genicam:{e.serial or e.index}", "serial": e.serial, "index": e.index,
           "vendor": e.vendor, "model": e.model, "status": e.access,
           "producer": ", ".join(files), "modes": [], "note": ""}
    try:
        ia = h.create(e.index)
    except Exception as err:  # noqa: BLE001 - the producer's own exception types
        out["status"] = "in use" if "InUse" in type(err).__name__ else "cannot open"
        out["note"] = producer._first_line(err)
        return out
    try:
        nm = ia.remote_device.node_map
        w, hgt = F.node(nm, "Width"), F.node(nm, "Height")
        formats = F.symbolics(F.node(nm, "PixelFormat"))
        if w is not None and hgt is not None:
            out["modes"].append(f"{int(w.min)}..{int(w.max)} x {int(hgt.min)}..{int(hgt.max)} "
                                f"(now {int(w.value)}x{int(hgt.value)})")
        out["pixel_formats"] = [f for f in formats if pixels.is_supported(f)]
        out["unsupported_pixel_formats"] = [f for f in formats if not pixels.is_supported(f)]
        features = [n for n in ("ExposureTime", "Gain", "BalanceRatio", "Gamma",
                                "TriggerSoftware") if F.node(nm, n) is not None]
        out["features"] = features
        out["status"] = "ready"
    finally:
        ia.destroy()
    return out
