"""A stand-in for an SO-101 leader arm, for tests: it replays a fixed motion.

Registered as the teleoperator type ``fake_so101_leader`` (LeRobot imports it through
``--teleop.discover_packages_path=fake_leader``). Its actions are what a calibrated leader
sends in LeRobot's units: ``<motor>.pos``, body joints in degrees, gripper 0 to 100. The
motion ramps from the home pose to :data:`TARGET` over :data:`RAMP_S` seconds, then holds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from lerobot.teleoperators.config import TeleoperatorConfig
from lerobot.teleoperators.teleoperator import Teleoperator

HOME = {
    "shoulder_pan.pos": 0.0,
    "shoulder_lift.pos": 0.0,
    "elbow_flex.pos": 0.0,
    "wrist_flex.pos": 0.0,
    "wrist_roll.pos": 0.0,
    "gripper.pos": 9.09,
}
TARGET = {
    "shoulder_pan.pos": 35.0,
    "shoulder_lift.pos": -25.0,
    "elbow_flex.pos": 30.0,
    "wrist_flex.pos": 20.0,
    "wrist_roll.pos": -40.0,
    "gripper.pos": 60.0,
}
RAMP_S = 1.0


@TeleoperatorConfig.register_subclass("fake_so101_leader")
@dataclass(kw_only=True)
class FakeSo101LeaderConfig(TeleoperatorConfig):
    ramp_s: float = RAMP_S


class FakeSo101Leader(Teleoperator):
    config_class = FakeSo101LeaderConfig
    name = "fake_so101_leader"

    def __init__(self, config: FakeSo101LeaderConfig) -> None:
        super().__init__(config)
        self.config = config
        self._started: float | None = None

    @property
    def action_features(self) -> dict[str, type]:
        return dict.fromkeys(HOME, float)

    @property
    def feedback_features(self) -> dict[str, type]:
        return {}

    @property
    def is_connected(self) -> bool:
        return self._started is not None

    def connect(self, calibrate: bool = True) -> None:
        self._started = time.perf_counter()

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        pass

    def configure(self) -> None:
        pass

    def get_action(self) -> dict[str, float]:
        progress = min((time.perf_counter() - self._started) / self.config.ramp_s, 1.0)
        return {name: HOME[name] + progress * (TARGET[name] - HOME[name]) for name in HOME}

    def send_feedback(self, feedback: dict[str, Any]) -> None:
        pass

    def disconnect(self) -> None:
        self._started = None
