"""LeRobot integration: the ``soarm`` EnvConfig and the ``sim_soarm_follower`` robot.

Importing this sub-package registers :class:`SoArmEnvConfig` under the name ``soarm``,
for ``lerobot-eval`` and ``lerobot-train``::

    lerobot-eval --env.discover_packages_path=gym_soarm.lerobot --env.type=soarm \\
        --env.task=LiftCube-v0 --policy.path=<checkpoint> --eval.n_episodes=10

and :class:`SimSoArmFollowerConfig` as the robot type ``sim_soarm_follower``, the
simulated arm for ``lerobot-teleoperate`` and ``lerobot-record`` with a real leader::

    lerobot-teleoperate --robot.discover_packages_path=gym_soarm.lerobot \\
        --robot.type=sim_soarm_follower --teleop.type=so101_leader --teleop.port=/dev/ttyACM0

It needs LeRobot (``pip install 'gym-soarm[lerobot]'``, Python >= 3.12 for LeRobot >= 0.5);
the rest of gym_soarm never imports LeRobot or torch.
"""

from __future__ import annotations

import sys

try:
    from lerobot.envs.configs import EnvConfig  # noqa: F401
except ImportError as exc:  # LeRobot (or one of its own dependencies) is missing
    if sys.version_info < (3, 12):
        raise ImportError(
            "gym_soarm.lerobot needs LeRobot, which needs Python >= 3.12; this is Python "
            f"{sys.version_info.major}.{sys.version_info.minor}, where the lerobot extra "
            "installs nothing. Create a Python 3.12+ environment and pip install "
            f"'gym-soarm[lerobot]' there. The import failed with: {exc}"
        ) from exc
    raise ImportError(
        "gym_soarm.lerobot needs LeRobot: pip install 'gym-soarm[lerobot]' "
        f"(LeRobot >= 0.5 needs Python >= 3.12). The import failed with: {exc}"
    ) from exc

from gym_soarm.lerobot.config import SoArmEnvConfig
from gym_soarm.lerobot.robot import SimSoArmFollower, SimSoArmFollowerConfig

__all__ = ["SimSoArmFollower", "SimSoArmFollowerConfig", "SoArmEnvConfig"]
