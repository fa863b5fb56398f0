"""LeRobot plugin of gym-soarm: importing it registers ``--env.type=soarm``.

LeRobot's command lines import every installed distribution named ``lerobot_env_*``;
this one only imports :mod:`gym_soarm.lerobot`, where the ``soarm`` EnvConfig and the
``sim_soarm_follower`` robot register themselves.
"""

from gym_soarm.lerobot import SimSoArmFollowerConfig, SoArmEnvConfig

__all__ = ["SimSoArmFollowerConfig", "SoArmEnvConfig"]
