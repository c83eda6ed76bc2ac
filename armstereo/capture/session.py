"""A capture as one unit of work: confirm live motion, run the checked plan into a recording
that is finished whatever happens (errors, Ctrl-C, SIGTERM), and say what was kept.

Shared by ``armstereo capture``, the demo and the baseline sweep.
"""

from __future__ import annotations

import contextlib
import logging
import signal
from collections.abc import Callable, Iterator
from pathlib import Path

from armstereo.capture.run import CapturePlanLike, CaptureResult, ViewHook, run_capture
from armstereo.devices import Arm, Camera
from armstereo.errors import ArmstereoError, UserAbort
from armstereo.robot.arm_model import ArmModel

log = logging.getLogger(__name__)

CONFIRM_WORD = "move"


def confirm_live_motion(*, live: bool, yes: bool, ask: Callable[[], str | None]) -> None:
    """Live motion (a real arm) needs ``yes`` or the word ``move`` typed at a terminal.

    ``ask`` prompts the user and returns the answer, or None when there is no terminal to ask
    at. Raises UserAbort (nothing moved) otherwise. Simulated arms need no confirmation.
    """
    if not live or yes:
        return
    answer = ask()
    if answer is None:
        raise UserAbort("live motion needs --yes or a typed confirmation (stdin is not a "
                        "terminal); nothing moved")
    if answer.strip().lower() != CONFIRM_WORD:
        raise UserAbort("not confirmed; nothing moved")


def capture_to_file(arm: Arm, camera: Camera, model: ArmModel, plan: CapturePlanLike, out: Path,
                    metadata: dict[str, str], *, image_format: str = "png",
                    progress: Callable[[str], None] | None = log.info,
                    on_view: ViewHook | None = None) -> CaptureResult:
    """Run the checked ``plan`` into the recording ``out``; the file is finished whatever
    happens (even SIGTERM). Errors name how many views were kept. ``on_view`` is passed to
    :func:`run_capture`."""
    from armstereo.recording import RecordingWriter

    plan.require_ok()  # before the file exists: a refused plan leaves nothing behind
    result = CaptureResult()
    metadata = {**camera.recording_metadata(), **metadata}
    writer = RecordingWriter(out, metadata=metadata, image_format=image_format)
    try:
        with sigterm_as_interrupt(), writer:
            try:
                run_capture(arm, camera, model, plan, writer, progress=progress, result=result,
                            on_view=on_view)
            except ArmstereoError as err:
                err.args = (f"{err}; {_kept(result, out)}",)
                raise
            except KeyboardInterrupt:
                raise UserAbort(f"interrupted; {_kept(result, out)}") from None
    except BaseException:
        if result.views == 0:  # ours and empty: no 0-view recording left behind
            Path(out).unlink(missing_ok=True)
        raise
    return result


def _kept(result: CaptureResult, out: Path) -> str:
    if result.views == 0:
        return f"no view was recorded, {out} not kept"
    return f"{result.views} view(s) kept in {out}"


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Treat SIGTERM like Ctrl-C so the arm stops and the recording is finished."""
    def handler(signum, frame):
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread (e.g. called from a test thread)
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
