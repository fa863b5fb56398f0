"""The environment: :class:`~gym_soarm.envs.env.SoArmEnv` over the step core.

:mod:`~gym_soarm.envs.core` (the step, written once over a physics backend),
:mod:`~gym_soarm.envs.env` (the Gymnasium environment of one simulation),
:mod:`~gym_soarm.envs.settings` (its settings object), :mod:`~gym_soarm.envs.control`
(actions to servo targets), :mod:`~gym_soarm.envs.infos` (infos as numbers for the
vector envs) and :mod:`~gym_soarm.envs.snapshot` (saved states) and :mod:`~gym_soarm.envs.presets`
(registered ids that apply a whole interface: LeRobot's tabletop contract).
"""
