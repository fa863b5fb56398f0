"""The environment: :class:`~gym_soarm.envs.env.SoArmEnv` over the step core.

:mod:`~gym_soarm.envs.core` (the step, written once over a physics backend),
:mod:`~gym_soarm.envs.env` (the Gymnasium environment of one simulation, a thin adapter
over its collaborators), :mod:`~gym_soarm.envs.settings` (its settings object and how its
arguments become one), :mod:`~gym_soarm.envs.world` (building the world the settings
describe, and a reset's draw), :mod:`~gym_soarm.envs.observations` (observations, infos
and camera images), :mod:`~gym_soarm.envs.spaces` (the observation space),
:mod:`~gym_soarm.envs.checks` (the action and reset-option checks),
:mod:`~gym_soarm.envs.control` (actions to servo targets), :mod:`~gym_soarm.envs.infos`
(infos as numbers for the vector envs), :mod:`~gym_soarm.envs.snapshot` (saved states)
and :mod:`~gym_soarm.envs.presets` (registered ids that apply a whole interface:
LeRobot's tabletop contract).
"""
