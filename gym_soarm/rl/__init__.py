"""Reinforcement learning on gym-soarm with Stable-Baselines3 (the ``gym-soarm[rl]`` extra).

* :mod:`gym_soarm.rl.hyperparams`: the settings of every (algorithm, task) recipe.
* :mod:`gym_soarm.rl.training`: :func:`~gym_soarm.rl.training.train`, checkpoints and
  learning curves (``python -m gym_soarm.train``).
* :mod:`gym_soarm.rl.evaluation`: a trained policy (or the scripted expert) scored on
  the benchmark's protocol (``python -m gym_soarm.evaluate``).
* :mod:`gym_soarm.rl.imitation`: BC and DAgger of the state experts from the state;
  :mod:`gym_soarm.rl.pixels` and :mod:`gym_soarm.rl.pixel_training`: the pixel student
  (cameras and joints) they teach; :mod:`gym_soarm.rl.runs`: what the runs share.

Importing this package needs no Stable-Baselines3; training and loading a policy do.
"""
