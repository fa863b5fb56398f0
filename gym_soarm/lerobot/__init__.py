"""LeRobot integration: the ``soarm`` EnvConfig for ``lerobot-eval`` and ``lerobot-train``.

Importing this sub-package registers :class:`SoArmEnvConfig` under the name ``soarm``::

    lerobot-eval --env.discover_packages_path=gym_soarm.lerobot --env.type=soarm \\
        --env.task=LiftCube-v0 --policy.path=<checkpoint> --eval.n_episodes=10

It needs LeRobot (``pip install 'gym-soarm[lerobot]'``, Python >= 3.12 for LeRobot >= 0.5);
the rest of gym_soarm never imports LeRobot or torch.
"""

from __future__ import annotations

try:
    from lerobot.envs.configs import EnvConfig  # noqa: F401
except ImportError as exc:  # LeRobot (or one of its own dependencies) is missing
    raise ImportError(
        "gym_soarm.lerobot needs LeRobot: pip install 'gym-soarm[lerobot]' "
        f"(LeRobot >= 0.5 needs Python >= 3.12). The import failed with: {exc}"
    ) from exc

from gym_soarm.lerobot.config import SoArmEnvConfig

__all__ = ["SoArmEnvConfig"]
