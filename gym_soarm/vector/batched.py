"""The batched vector env: all N simulations stepped in one call (``mujoco.batch``, or MuJoCo
Warp).

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point")`` builds a
:class:`BatchedVectorEnv` for state observations (``vector_env="auto"``, the default;
``vector_env="batched"`` asks for it whatever the observations).

* One process. Every control step sets the N simulations' servo targets and steps them
  all with one call to :class:`mujoco.batch.Batch` (MuJoCo's own thread pool, the GIL
  released, bit-identical to stepping each alone), then scores the whole batch once:
  the task's evaluation, reward terms, success, info and ``state`` observation are array
  code over the batch (:mod:`gym_soarm.tasks.base`), so no per-environment Python runs
  on a step. The joint control modes are converted for the whole batch too; the
  end-effector modes, a servo delay and the STS3215 servo model run per environment.
* Each environment is still a :class:`~gym_soarm.envs.env.SoArmEnv`, which resets (placement,
  variation, reset options, snapshots), renders and answers ``call``/``get_attr``; its
  simulation is copied into the batch at its reset and after a ``call`` or ``set_attr``,
  and back from it when it is asked for (an object that ``get_attr`` hands out and that
  is changed later is not copied back: change a simulation through ``call``). Pixel observations render each environment this way: the process-based
  :class:`~gym_soarm.vector.SoArmVectorEnv` is faster for them, and ``"auto"`` picks it.
* The episodes are those of N single ``gym.make`` environments, bit for bit: the same
  observations, rewards, terminations, truncations and infos (batched as
  ``SyncVectorEnv`` batches them), in each of the three autoreset modes.
* A simulation that diverges (a MuJoCo warning or error, NaN, an object thrown off the
  table, a Warp world past its budget of contacts or constraint rows) truncates its own
  episode with a warning naming its index, as a single environment does; the others go on.
* ``physics="warp"`` (``vector_env="warp"``) steps the worlds on MuJoCo Warp
  (:mod:`gym_soarm.sim.warp_backend`): the tasks then score torch tensors on the device,
  and the per-episode values the tasks keep live there too.
* ``array_api`` (:mod:`gym_soarm.vector.views`): ``"numpy"`` (default, the NumPy view)
  or ``"torch"`` (torch tensors on :attr:`BatchedVectorEnv.device`). The episode
  bookkeeping (time limits, autoresets, divergences, resets) runs on the host; with the
  torch view a step reads from the device one ``(3, N)`` boolean array (the worlds that
  diverged or overflowed, and succeeded: :meth:`StepCore.step
  <gym_soarm.envs.core.StepCore.step>`) and sends the host's values to it (the servo
  targets, the step counts, terminations, truncations and ``_key`` masks). Actions
  given as tensors are copied to the host (the control modes convert them in NumPy);
  ``environment_state_agent_pos`` in units other than radians converts the joint angles
  on the host; a divergence's warning, a reset and ``call``/``synced_envs`` read their
  worlds from the device.
"""

from __future__ import annotations

import copy
import warnings
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv

from gym_soarm import constants
from gym_soarm.envs.control import JOINT_DELTA, JOINT_POS, NormalizedControl
from gym_soarm.envs.core import StepCore
from gym_soarm.envs.env import SoArmEnv
from gym_soarm.sim.arrays import SimArrays, in_namespace, to_numpy
from gym_soarm.sim.backends import Backend, BatchBackend
from gym_soarm.sim.warp_backend import WarpBackend
from gym_soarm.validation import check_choice, check_int
from gym_soarm.vector.base import SoArmVectorBase, StepReturn
from gym_soarm.vector.choice import (
    VECTOR_ENVS,
    check_batchable,
    check_numpy_only,
    check_physics,
    wants_batched,
)
from gym_soarm.vector.common import (
    leaf_value,
    nest,
)
from gym_soarm.vector.views import (
    ARRAY_APIS,
    FLOAT,
    TorchView,
    column,
    make_view,
    put,
    row_of,
    zeros_where,
)
from gym_soarm.vector.workers import cpu_count


class BatchedVectorEnv(SoArmVectorBase):
    """``num_envs`` :class:`~gym_soarm.envs.env.SoArmEnv` simulations stepped as one batch.

    Made by ``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point")``
    for state observations; every keyword ``gym.make`` takes is passed to each
    environment.

    Args:
        num_envs: number of environments (at least 1).
        max_episode_steps: truncate an episode after this many steps, as Gymnasium's
            ``TimeLimit`` does (``make_vec`` passes the id's limit); None for no limit.
        autoreset_mode: ``"NextStep"`` (default), ``"SameStep"`` or ``"Disabled"``, or a
            :class:`gymnasium.vector.AutoresetMode`.
        num_threads: the threads that step the simulations (default: the CPUs this
            process may use, at most ``num_envs``).
        copy: return fresh observation arrays on every call (default). With False the
            same arrays are filled again by the next call.
        physics: ``"mujoco"`` (default: one ``mujoco.batch``, bit for bit the single
            envs' episodes) or ``"warp"`` (MuJoCo Warp, float32:
            :mod:`gym_soarm.sim.warp_backend`).
        device: with ``physics="warp"``, the Warp device: ``"cuda"`` (default),
            ``"cuda:N"`` or ``"cpu"``.
        array_api: the arrays it returns (:mod:`gym_soarm.vector.views`): ``"numpy"``
            (default: the NumPy view, NumPy arrays on the host as ``SyncVectorEnv``
            batches them) or ``"torch"`` (torch tensors on :attr:`device`: the Warp
            device, or the CPU for ``physics="mujoco"``).
        **env_kwargs: the arguments of :class:`~gym_soarm.envs.env.SoArmEnv`.

    Raises:
        ValueError: a bad ``num_envs``, ``num_threads``, ``autoreset_mode``,
            ``array_api`` or environment argument, before anything is built.
    """

    def __init__(
        self,
        num_envs: int,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        num_threads: int | None = None,
        copy: bool = True,
        physics: str = "mujoco",
        device: str | None = None,
        array_api: str = "numpy",
        **env_kwargs: Any,
    ) -> None:
        self.closed = True
        num_envs = self._check_arguments(num_envs, max_episode_steps, autoreset_mode, copy)
        self.device = check_physics(physics, device, array_api, env_kwargs)
        """Where the simulations' arrays live (torch's name of the Warp device)."""
        self._out = make_view(array_api, self.device)
        self.array_api = array_api
        if num_threads is None:
            num_threads = cpu_count()
        self.num_threads = min(check_int("num_threads", num_threads, 1), num_envs)

        first = SoArmEnv(**env_kwargs)  # checks every argument
        self.envs: list[SoArmEnv] = [first]
        try:
            self.envs += [SoArmEnv(**env_kwargs) for _ in range(num_envs - 1)]
        except BaseException:
            for env in self.envs:
                env.close()
            raise
        self._take_spaces(first)
        self._obs_arrays = [self._out.zeros((num_envs, *s), dtype) for _, s, dtype in self._leaves]

        self._task = first.task_logic  # scores the batch; per-env values live in _episode
        self._backend = self._build_backend(physics)
        host = self._task.host_episode_values  # read as Python values: kept on the host
        self._episode = {
            name: np.zeros((num_envs, *shape))
            if name in host
            else zeros_where((num_envs, *shape), physics, self.device)
            for name, shape in self._task.episode_shapes.items()
        }
        # The step, written once (gym_soarm.envs.core), over the whole batch.
        self._core = StepCore(
            self._task, self._backend, self._episode, substeps=first.timing.substeps
        )
        self._sim = self._core.arrays()
        self._commanded = np.zeros((num_envs, len(constants.JOINT_NAMES)))
        self._steps = np.zeros(num_envs, dtype=np.int64)  # this episode's, as the env's
        self._in_batch = np.zeros(num_envs, dtype=np.bool_)  # env i's own data is stale
        self._own_control = np.zeros(num_envs, dtype=np.bool_)
        self._last_infos: dict[str, Any] = {}  # the last step's (for a divergence)
        self._reset_infos: list[dict[str, Any] | None] = [None] * num_envs
        self._info_from_reset = np.zeros(num_envs, dtype=np.bool_)  # last info: the reset's
        self._sparse = np.zeros(num_envs, dtype=np.bool_)  # reward_type, per environment
        self._control = self._batch_control(first)
        self._instructions = np.empty(num_envs, dtype=object)
        self.closed = False

    def _build_backend(self, physics: str) -> Backend:
        """The backend of the environments' simulations (they are closed if it fails)."""
        first = self.envs[0]
        try:
            check_batchable(first.task_spec)
            models = [env.physics.model.ptr for env in self.envs]
            index = first.physics.sim_index
            if physics == "warp":
                return WarpBackend(models, self.device, index)
            return BatchBackend(models, self.num_threads, index)
        except BaseException:
            for env in self.envs:
                env.close()
            raise

    @staticmethod
    def _batch_control(env: SoArmEnv) -> Any:
        """The control mode that converts the whole batch's actions at once, or None
        where each environment converts its own (end-effector modes, LeRobot units)."""
        control = env.control
        mode = control.mode if isinstance(control, NormalizedControl) else control
        if mode.name == JOINT_DELTA or (mode.name == JOINT_POS and env.units == "radians"):
            return control
        return None

    # --- moving simulations between the batch and the environments ----------------------
    def _load(self, i: int) -> None:
        """Copy environment ``i`` (just reset or restored) into the batch."""
        env = self.envs[i]
        self._backend.load(i, env.physics)
        for name, values in env.task_logic.episode.items():
            put(self._episode[name], i, values[0])
        self._commanded[i] = env.commanded_targets
        # A servo delay (drawn at each reset with physics randomisation) or the servo
        # model: this environment converts its own actions.
        self._own_control[i] = not env.servo_chain.passes_through
        self._steps[i] = env.step_count
        self._in_batch[i] = False
        self._instructions[i] = env.task_description
        self._sparse[i] = env.reward_type == "sparse"
        self._sim.clear()

    def _unload(self, i: int) -> SoArmEnv:
        """Environment ``i`` with the batch's simulation and episode values copied back."""
        env = self.envs[i]
        if self._in_batch[i]:
            self._backend.unload(i, env.physics)
            for name, values in env.task_logic.episode.items():
                values[0] = to_numpy(self._episode[name][i])
            env.servo_chain.commanded = self._commanded[i].copy()
            env.step_count = int(self._steps[i])
            self._in_batch[i] = False
        return env

    def synced_envs(self) -> tuple[SoArmEnv, ...]:
        """Every environment with its world's state now (copied from the batch where it
        stepped since): to read (an expert, an observer). A change made to one directly
        is not copied back into the batch: change a simulation through :meth:`call`."""
        self._check_open()
        return tuple(self._unload(i) for i in range(self.num_envs))

    # --- the transport under SoArmVectorBase -------------------------------------------
    def _reset(
        self, seeds: list[int | None], options: dict[str, Any] | None, mask: np.ndarray | None
    ) -> dict[str, Any]:
        if mask is None:
            mask = np.ones(self.num_envs, dtype=np.bool_)
        infos: dict[str, Any] = {}
        for i in np.flatnonzero(mask).tolist():
            obs, info = self._reset_one(i, seeds[i], options)
            self._write_obs(i, obs)
            infos = self._add_info(infos, info, i)
        self._backend.set_models()  # the resets edited the models
        return self._out.infos(infos)

    def _reset_one(
        self, i: int, seed: int | None, options: dict[str, Any] | None
    ) -> tuple[Any, dict[str, Any]]:
        obs, info = self.envs[i].reset(seed=seed, options=options)
        self._load(i)  # the reset replaced the batch's state
        self._reset_infos[i] = info
        self._info_from_reset[i] = True
        return obs, info

    def _write_obs(self, i: int, obs: Any) -> None:
        for (path, _, _), array in zip(self._leaves, self._obs_arrays, strict=True):
            put(array, i, leaf_value(obs, path))

    def _add_info(
        self, vector_infos: dict[str, Any], env_info: dict[str, Any], env_num: int
    ) -> dict[str, Any]:
        """Gymnasium's, with one environment's values as the batch's arrays hold them
        (host values into the torch view's tensors)."""
        env_info = self._out.matching(vector_infos, env_info)
        return super()._add_info(vector_infos, env_info, env_num)

    def _step(self, actions: np.ndarray, restart: np.ndarray, time_up: np.ndarray) -> StepReturn:
        """One step of the batch (the clock's plan and the divergences of the stepping
        environments), as N single environments would take it."""
        array = actions.astype(np.float64)
        mode, out = self.autoreset_mode, self._out
        stepping = ~restart
        ids = np.flatnonzero(stepping)
        self._steps[ids] += 1
        self._in_batch[ids] = True
        result = self._core.step(
            self._targets(array, ids), self._steps, self.envs[0].step_limit, self._sparse, ids
        )
        self._sim = result.sim
        reasons = result.diverged
        rewards = out.values(result.reward, FLOAT)
        obs_rows = self._observations()
        infos = self._infos(self._sim, result.evaluation, result.success, result.terms)
        terminated = result.host_success & stepping
        truncated = time_up.copy()
        last_obs = {i: [out.copy(a[i]) for a in self._obs_arrays] for i in sorted(reasons)}
        for array_, rows in zip(self._obs_arrays, obs_rows, strict=True):
            out.rows(array_, rows, ids)
        if reasons:
            self._truncate_diverged(reasons, last_obs, rewards, terminated, truncated, infos)
        self._info_from_reset[stepping] = False  # their last info is this step's
        ended = (terminated | truncated) & stepping
        self._host_ends = (terminated, truncated)  # what _note_ends reads
        if mode is AutoresetMode.SAME_STEP and ended.any():
            infos = self._reset_ended(np.flatnonzero(ended), infos)
        for i in np.flatnonzero(restart).tolist():
            obs, info = self._reset_one(i, None, None)
            self._write_obs(i, obs)
            rewards[i] = 0.0
            infos = self._add_info(infos, info, i)
        if restart.any():
            self._backend.set_models()
        self._last_infos = infos = out.infos(infos)
        ends = (out.values(terminated), out.values(truncated))
        return self._batched_obs(), rewards, *ends, infos

    def _targets(self, actions: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """The servo targets (rad) of the stepping environments ``ids``: converted for the
        whole batch at once, or by each environment's servo chain (a delay, the servo
        model, the end-effector modes)."""
        if self._control is not None and not self._own_control.any():
            targets = self._control.targets(actions[ids], self._commanded[ids])
            self._commanded[ids] = targets
            return targets
        targets = np.empty((len(ids), len(constants.JOINT_NAMES)))
        for k, i in enumerate(ids.tolist()):
            chain = self.envs[i].servo_chain
            chain.commanded = self._commanded[i].copy()
            targets[k] = chain.targets(actions[i].copy())
            self._commanded[i] = chain.commanded
        return targets

    def _observations(self) -> list[Any]:
        """Every environment's observation of this step, one array of the view a leaf."""
        first, sim, out = self.envs[0], self._sim, self._out
        if first.obs_type == "state":
            commanded = in_namespace(sim.xp, self._commanded, sim.qpos)
            return [out.values(self._core.state_observation(sim, commanded), np.float32)]
        if first.obs_type == "environment_state_agent_pos":
            angles = sim.joint_angles()
            if first.units != "radians":  # the units' conversion is NumPy's
                angles = first.joint_units.from_radians(to_numpy(angles))
            values = {
                ("agent_pos",): angles,
                ("environment_state",): self._core.environment_state(sim),
            }
            return [out.values(values[path], dtype) for path, _, dtype in self._leaves]
        # Pixels: each environment renders its own copy of the simulation.
        rows = [np.zeros((self.num_envs, *shape), dtype) for _, shape, dtype in self._leaves]
        for i in range(self.num_envs):
            env = self._unload(i)
            obs = env.observation()
            for (path, _, _), array in zip(self._leaves, rows, strict=True):
                array[i] = leaf_value(obs, path)
        return [out.values(array) for array in rows]

    def _infos(
        self, sim: SimArrays, evaluation: dict[str, Any], success: Any, terms: dict[str, Any]
    ) -> dict[str, Any]:
        """This step's infos: the values computed with the simulations in the view, the
        host's as they are (the view takes them in when the step returns)."""
        n, out = self.num_envs, self._out
        ones = np.ones(n, dtype=np.bool_)
        infos: dict[str, Any] = {"is_success": out.values(success), "_is_success": ones}
        task_info, gripper = self._core.info_values(sim, evaluation)
        for key, value in task_info.items():
            infos[key] = column(value, n, out)
            infos[f"_{key}"] = ones
        infos["gripper_pos"] = out.values(gripper)
        infos["_gripper_pos"] = ones
        reward_terms: dict[str, Any] = {}
        for name, value in terms.items():
            reward_terms[name] = out.values(value, FLOAT)
            reward_terms[f"_{name}"] = ones
        infos["reward_terms"] = reward_terms
        infos["_reward_terms"] = ones
        infos["task"] = self._instructions.copy()
        infos["_task"] = ones
        infos["physics_unstable"] = out.values(np.zeros(n, dtype=np.bool_))
        infos["_physics_unstable"] = ones
        control_keys = self.envs[0].control.info()
        if control_keys:  # the end-effector modes: each environment converted its own action
            rows = [env.control.info() for env in self.envs]
            for key in control_keys:
                infos[key] = column([row[key] for row in rows], n, out)
                infos[f"_{key}"] = ones
        return infos

    def _truncate_diverged(
        self,
        reasons: dict[int, str],
        last_obs: dict[int, list[Any]],
        rewards: Any,
        terminated: np.ndarray,
        truncated: np.ndarray,
        infos: dict[str, Any],
    ) -> None:
        """End the diverged episodes as a single environment does: the last sound
        observation and info, reward 0 and every reward term 0, truncated."""
        for i, rows in last_obs.items():
            warnings.warn(
                f"The physics of environment {i} diverged ({reasons[i]}); its episode is "
                "truncated (the other environments go on).",
                RuntimeWarning,
                stacklevel=3,
            )
            rewards[i] = 0.0
            terminated[i] = False
            truncated[i] = True
            for array, row in zip(self._obs_arrays, rows, strict=True):
                array[i] = row
            # The last sound info: the reset's, or the previous step's row.
            reset_info = self._reset_infos[i] if self._info_from_reset[i] else None
            previous = self._last_infos
            for key, value in infos.items():
                if key.startswith("_") or isinstance(value, dict):
                    continue
                if reset_info is not None and key in reset_info:
                    put(value, i, reset_info[key])
                elif reset_info is None and key in previous:
                    put(value, i, previous[key][i])
            # As a single environment, it refuses to go on until reset.
            self.envs[i].end_episode(
                f"the previous step truncated the episode because the physics diverged "
                f"({reasons[i]})"
            )
            infos["is_success"][i] = False
            infos["physics_unstable"][i] = True
            for name, value in infos["reward_terms"].items():
                if not name.startswith("_"):
                    value[i] = 0.0

    def _reset_ended(self, ended: np.ndarray, infos: dict[str, Any]) -> dict[str, Any]:
        """``SAME_STEP``: keep the ended episodes' last observations and infos, reset them."""
        if isinstance(self._out, TorchView):
            finals = self._out_finals(ended, infos)
        else:
            finals = {}
            for i in ended.tolist():
                final_obs = nest(
                    {
                        path: a[i].copy()
                        for (path, _, _), a in zip(self._leaves, self._obs_arrays, strict=True)
                    }
                )
                finals[i] = (
                    final_obs,
                    {k: row_of(v, i) for k, v in infos.items() if not k.startswith("_")},
                )
        for i in ended.tolist():
            obs, info = self._reset_one(i, None, None)
            self._write_obs(i, obs)
            infos = self._add_info(infos, info, i)
        self._backend.set_models()
        if isinstance(self._out, TorchView):
            return {**infos, **finals}
        return self._add_finals(infos, finals)

    def _out_finals(self, ended: np.ndarray, infos: dict[str, Any]) -> dict[str, Any]:
        """The torch view's ``final_obs`` and ``final_info``: batched tensors, zeros in
        the rows of the environments that did not end (the masks mark those that did)."""
        out = self._out
        mask = np.zeros(self.num_envs, dtype=np.bool_)
        mask[ended] = True
        rows = out.values(mask)
        final_obs = nest(
            {
                path: out.ended_rows(a, rows)
                for (path, _, _), a in zip(self._leaves, self._obs_arrays, strict=True)
            }
        )
        final_info = out.finals(out.infos(infos), rows, mask)
        return {
            "final_obs": final_obs,
            "_final_obs": rows,
            "final_info": final_info,
            "_final_info": rows,
        }

    # --- calls and attributes --------------------------------------------------------------
    def _call(self, indices: list[int], name: str, args: tuple, kwargs: dict) -> list[Any]:
        try:
            return [self._call_one(i, name, args, kwargs) for i in indices]
        finally:
            self._backend.set_models()

    def _call_one(self, i: int, name: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        """Call ``name`` on environment ``i`` as the batch left it; whatever the call
        changed (a reset, a restored snapshot, a nudged object) goes back into the batch."""
        self._check_open()
        env = self._unload(i)
        attribute = getattr(env, name)
        result = attribute(*args, **kwargs) if callable(attribute) else attribute
        self._load(i)
        return result

    def _get_attr(self, name: str) -> list[Any]:
        return [getattr(self._unload(i), name) for i in range(self.num_envs)]

    def _set_attr(self, name: str, values: list[Any]) -> None:
        for i, value in enumerate(values):
            setattr(self._unload(i), name, copy.copy(value))
            self._load(i)
        self._backend.set_models()

    def close_extras(self, **kwargs: Any) -> None:
        """Close every environment and release the batch and its threads."""
        # Every reference to the batch goes (its bound arrays hold it too).
        if self._backend is not None:
            self._backend.close()
        self._backend = self._core = self._sim = None
        errors = []
        for env in self.envs:
            try:
                env.close()
            except Exception as exc:  # close the others first, then raise the first
                errors.append(exc)
        if errors:
            raise errors[0]


_PROCESS_KEYWORDS = ("num_processes", "start_method")


def make_vector_env(num_envs: int, vector_env: str = "auto", **kwargs: Any) -> VectorEnv:
    """The native vector env of ``num_envs`` environments (the ids' vector entry point).

    Args:
        num_envs: number of environments.
        vector_env: ``"batched"`` (:class:`BatchedVectorEnv`: one ``mujoco.batch``, the
            tasks scored as arrays), ``"warp"`` (the same env on MuJoCo Warp, with a
            ``device`` keyword: ``"cuda"``, ``"cuda:N"`` or ``"cpu"``), ``"processes"``
            (:class:`~gym_soarm.vector.SoArmVectorEnv`: worker processes, each stepping
            its block of environments) or ``"auto"`` (default): batched for state
            observations, processes for pixels or where ``num_processes`` or
            ``start_method`` is given.
        **kwargs: the vector env's own arguments and ``gym.make``'s keywords;
            ``array_api`` (``"numpy"``, the default, or ``"torch"``:
            :mod:`gym_soarm.vector.views`) for the batched and Warp envs.

    Raises:
        ValueError: an unknown ``vector_env`` or ``array_api``, process arguments for
            the batched env, or ``array_api="torch"`` for the process-based env.
    """
    from gym_soarm.vector.processes import SoArmVectorEnv

    check_choice("vector_env", vector_env, VECTOR_ENVS)
    array_api = check_choice("array_api", kwargs.pop("array_api", "numpy"), ARRAY_APIS)
    process_args = [k for k in _PROCESS_KEYWORDS if kwargs.get(k) is not None]
    if vector_env == "auto":
        vector_env = "batched" if wants_batched(kwargs) and not process_args else "processes"
    if vector_env == "warp":
        kwargs["physics"] = "warp"
    if vector_env == "processes":
        check_numpy_only(array_api)
        kwargs.pop("num_threads", None)
        return SoArmVectorEnv(num_envs, **kwargs)
    if process_args:
        raise ValueError(
            f"{' and '.join(process_args)} apply to vector_env='processes'; the batched env "
            "runs in one process (its threads: num_threads). Remove them or pass "
            "vector_env='processes'."
        )
    for key in _PROCESS_KEYWORDS:
        kwargs.pop(key, None)
    return BatchedVectorEnv(num_envs, array_api=array_api, **kwargs)


__all__ = ["VECTOR_ENVS", "BatchedVectorEnv", "make_vector_env", "wants_batched"]
