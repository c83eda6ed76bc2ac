"""Faults the mock backends inject on request (CLI: ``--inject-fault NAME[@N]``, repeatable).

A :class:`FaultPlan` is an immutable description; the backends keep the counters: the mock arm
counts the moves it starts (``move_joints`` and ``move_linear`` together, from 1) and asks
:meth:`FaultPlan.move_fault`; the mock camera counts its grabs (from 1) and asks
:meth:`FaultPlan.grab_fault`. The same plan can be handed to both, and to several captures in a
row (each backend instance starts counting at 1), so a run is deterministic.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from armstereo.errors import ConfigError

# name -> (what it counts, default N, description)
FAULTS: dict[str, tuple[str, int, str]] = {
    "disconnect": ("move", 2, "the link drops part way through move N"),
    "protective-stop": ("move", 2, "a protective stop halts the arm part way through move N"),
    "stuck-move": ("move", 2, "move N stalls part way and never finishes (caller's timeout)"),
    "camera-timeout": ("grab", 2, "grab N delivers no frame (CameraTimeout)"),
}
FAULT_NAMES = tuple(FAULTS)
# Where along its path (fraction of the move's duration) a faulted move halts.
FAULT_FRACTION = 0.5


@dataclass(frozen=True)
class Fault:
    """One injected fault: ``name`` at the ``at``-th move or grab (1-based)."""

    name: str
    at: int

    @property
    def kind(self) -> str:
        """``"move"`` (arm faults) or ``"grab"`` (camera faults)."""
        return FAULTS[self.name][0]

    def __str__(self) -> str:
        return f"{self.name}@{self.at}"


@dataclass(frozen=True)
class FaultPlan:
    """The faults to inject; at most one per move and one per grab."""

    faults: tuple[Fault, ...] = ()

    @classmethod
    def parse(cls, specs: Iterable[str]) -> FaultPlan:
        """Parse ``NAME`` or ``NAME@N`` items (also comma-separated) into a plan.

        ``N`` (1-based) defaults to 2: the second move or grab, so the first view of a capture
        is recorded before the fault. Raises ConfigError naming the valid faults.
        """
        faults: list[Fault] = []
        for spec in specs:
            for item in str(spec).split(","):
                if item.strip():
                    faults.append(_parse_one(item.strip().lower()))
        seen: dict[tuple[str, int], Fault] = {}
        for f in faults:
            other = seen.setdefault((f.kind, f.at), f)
            if other is not f:
                raise ConfigError(f"--inject-fault {other} and {f} both target {f.kind} {f.at}; "
                                  f"give each {f.kind} at most one fault")
        return cls(tuple(faults))

    def __bool__(self) -> bool:
        return bool(self.faults)

    def move_fault(self, n: int) -> Fault | None:
        """The arm fault due during the ``n``-th move (1-based), if any."""
        return self._find("move", n)

    def grab_fault(self, n: int) -> Fault | None:
        """The camera fault due at the ``n``-th grab (1-based), if any."""
        return self._find("grab", n)

    def describe(self) -> list[str]:
        """One line per fault, e.g. ``disconnect@2: the link drops part way through move 2``."""
        return [f"{f}: {FAULTS[f.name][2].replace(' N', f' {f.at}')}" for f in self.faults]

    def _find(self, kind: str, n: int) -> Fault | None:
        for f in self.faults:
            if f.kind == kind and f.at == n:
                return f
        return None


def _parse_one(item: str) -> Fault:
    name, sep, count = item.partition("@")
    if name not in FAULTS:
        raise ConfigError(f"unknown fault {name!r}; valid faults: {', '.join(FAULT_NAMES)} "
                          f"(optionally NAME@N)")
    if not sep:
        return Fault(name, FAULTS[name][1])
    if not count.isdigit() or int(count) < 1:
        raise ConfigError(f"--inject-fault {item}: N must be a whole number >= 1 "
                          f"(the {FAULTS[name][0]} to fail), got {count!r}")
    return Fault(name, int(count))
