"""Config of the Universal Robots arm backend (registry name ``ur``)."""

from __future__ import annotations

from dataclasses import dataclass, field

from armstereo import validate
from armstereo.errors import ConfigError
from armstereo.flags import option


@dataclass(frozen=True, kw_only=True)
class URArmConfig:
    """A UR controller at ``host``; ``upper_range_registers`` uses RTDE input registers 24-47
    (to coexist with a fieldbus adapter that holds the lower ones)."""

    host: str | None = field(default=None, metadata=option(
        "--host", "UR controller address (with --arm ur)"))
    upper_range_registers: bool = field(default=False, metadata=option(
        "--upper-range-registers", "UR arm: use RTDE registers 24-47 (a fieldbus holds 0-23)",
        action="store_true"))

    def __post_init__(self) -> None:
        if not self.host or not str(self.host).strip():
            raise ConfigError("--arm ur needs --host IP (the controller's address)")
        object.__setattr__(self, "host", validate.host(self.host, "--host"))
