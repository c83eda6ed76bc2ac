"""Stop-and-shoot capture: plan and check the baseline path, then move, settle, grab, record."""

from armstereo.capture.plan import CapturePlan, CaptureSettings, Workspace, plan_capture
from armstereo.capture.run import CaptureResult, run_capture

__all__ = ["CapturePlan", "CaptureSettings", "Workspace", "plan_capture", "CaptureResult",
           "run_capture"]
