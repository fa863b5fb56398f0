"""Vector environments: N simulations behind one Gymnasium ``VectorEnv``.

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point",
vector_env=...)`` picks one (:func:`~gym_soarm.vector.batched.make_vector_env`):

* ``"batched"`` (:class:`~gym_soarm.vector.batched.BatchedVectorEnv`): every simulation
  in one ``mujoco.batch``, stepped by the step core (:mod:`gym_soarm.envs.core`) over
  the whole batch at once; for state observations. ``"warp"``: the same env on MuJoCo
  Warp. Both return NumPy arrays, or torch tensors with ``array_api="torch"``
  (:mod:`~gym_soarm.vector.views`).
* ``"processes"`` (:class:`~gym_soarm.vector.processes.SoArmVectorEnv`): blocks of
  single environments in worker processes; for pixels.

Both are transport under :class:`~gym_soarm.vector.base.SoArmVectorBase`, which holds
the ``VectorEnv`` shell (the argument, seed and action checks, the autoreset state, the
final observations and infos, ``call``/``get_attr``/``set_attr``/``render``/``close``);
:mod:`~gym_soarm.vector.common` holds the helpers they share (seeds, reset masks,
action checks, observation leaves), :mod:`~gym_soarm.vector.choice` the choice of a
vector env and the checks of its keywords, and :mod:`~gym_soarm.vector.workers` the
worker processes.
"""

from __future__ import annotations

from gym_soarm.vector.batched import VECTOR_ENVS, BatchedVectorEnv, make_vector_env
from gym_soarm.vector.common import parse_seeds
from gym_soarm.vector.processes import SoArmVectorEnv, WorkerDiedError

__all__ = [
    "VECTOR_ENVS",
    "BatchedVectorEnv",
    "SoArmVectorEnv",
    "WorkerDiedError",
    "make_vector_env",
    "parse_seeds",
]
