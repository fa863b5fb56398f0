"""The expert as a teacher: behaviour cloning with DART noise, DAgger, and PPO with a
behaviour-cloning term (SPEC 22).

:func:`train_imitation` (``python -m gym_soarm.train --algo bc|dagger``) learns a state
policy from the task's scripted expert (:func:`gym_soarm.expert.make_expert`) in the
recipe's environment (:mod:`gym_soarm.rl.hyperparams`: state observations, normalised
``joint_delta`` actions) and writes a policy folder as :func:`gym_soarm.rl.training.train`
does, so ``python -m gym_soarm.evaluate``, :class:`gym_soarm.rl.evaluation.TrainedPolicy`
and ``--algo ppo --init DIR`` load it:

* ``model.zip``: the policy as a Stable-Baselines3 ``PPO`` model (``MlpPolicy``); its
  actor (``mlp_extractor`` policy branch and ``action_net``) is trained by regression of
  its mean action on the expert's actions, its value branch is left untrained;
* ``vecnormalize.pkl``: observation statistics of the first demonstrations (an SB3
  ``VecNormalize`` with ``training=False``), as PPO runs save theirs;
* ``demos.npz``: the aggregated data set: ``obs`` (raw observations), ``actions`` (the
  expert's clean labels), ``executed`` (the actions the environment received),
  ``episode`` and ``round`` per step;
* ``settings.json`` (format ``gym_soarm.policy/1``), ``curve.csv`` (one row per round:
  ``round``, ``env_steps``, ``samples``, ``wall_s``, ``success_rate``, ``mean_return``,
  ``episodes``) and ``curve.png``.

**BC**: ``demos`` expert episodes with DART noise (the executed action is the expert's
plus Gaussian noise of standard deviation ``dart_std``, clipped to [-1, 1]; the label is
the clean expert action), then ``epochs`` of regression. **DAgger**: round 0 is BC on
``demos`` episodes; in each round r = 1 .. R, ``episodes_per_round`` episodes where each
step executes the expert's action with probability ``beta0 * beta_decay ** r`` and the
learner's otherwise; the expert labels every visited state, the data is aggregated and
the policy retrained (warm start, ``round_epochs``) and evaluated; the folder keeps the
policy of the round that scored best (the latest among equals), with the data and the
curve of every round.

The reset seeds of the training episodes are ``100_000 * (seed + 1) + 1_000 * round + k``:
never the protocol's (``1000 + k``) nor another training seed's.

The expert is called exactly once per step of each environment, right after the
environment's reset (``expert.reset()``) or step: with a Markov expert (a pure function
of the environment's state) this labels any state; the clock-based experts of earlier
versions still label the states they are stepped through.

:class:`gym_soarm.rl.bc_ppo.BCRegularizedPPO` is the PPO of ``--algo ppo --init DIR``
(:func:`gym_soarm.rl.training.train`): after each PPO update it takes as many gradient
steps on ``bc_coef * MSE(actor mean(obs_demo), expert action)`` over minibatches of the
demonstrations, ``bc_coef`` decaying by ``bc_decay`` per update.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import os
import pickle
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.envs.settings import merge_keywords
from gym_soarm.rl.curves import TrainResult, pyplot
from gym_soarm.rl.dagger import Gathering, ImitationTrainer
from gym_soarm.rl.evaluation import (
    MODEL_FILE,
    NORMALIZE_FILE,
    make_env,
    require_sb3,
)
from gym_soarm.rl.hyperparams import IMITATION, override, pixel_recipe, recipe
from gym_soarm.rl.pixel_training import PixelTrainer
from gym_soarm.rl.pixels import (
    PIXEL_MODEL_FILE,
    PIXEL_OBS_TYPES,
    check_pixel_settings,
    demos_within_store,
    is_pixel_env,
    store_bound,
)
from gym_soarm.rl.runs import (
    RunFolder,
    check_run_numbers,
    episode_weights,
    training_seeds,
)
from gym_soarm.tasks import get_task
from gym_soarm.validation import ArgumentTypeError, check_int

logger = logging.getLogger(__name__)

DEMOS_FILE = "demos.npz"
OBS_VAR_FLOOR = 1e-4
"""The smallest variance of an observation value in the normalisation (a value the
demonstrations never change is not blown up)."""


# --------------------------------------------------------------------------- data


@dataclasses.dataclass
class Dataset:
    """Steps of expert-labelled episodes: raw observations, the expert's (clean) action
    for each, the action executed there, the episode and the round of each step."""

    obs: np.ndarray
    actions: np.ndarray
    executed: np.ndarray
    episode: np.ndarray
    round: np.ndarray

    @classmethod
    def empty(cls, obs_dim: int, act_dim: int) -> Dataset:
        return cls(
            np.zeros((0, obs_dim), np.float32),
            np.zeros((0, act_dim), np.float32),
            np.zeros((0, act_dim), np.float32),
            np.zeros(0, np.int64),
            np.zeros(0, np.int64),
        )

    def __len__(self) -> int:
        return len(self.obs)

    def extend(self, other: Dataset) -> Dataset:
        fields = dataclasses.fields(self)
        return Dataset(
            *(np.concatenate([getattr(self, f.name), getattr(other, f.name)]) for f in fields)
        )

    def save(self, path: Path) -> None:
        np.savez_compressed(path, **dataclasses.asdict(self))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Dataset:
        with np.load(path) as data:
            return cls(*(data[f.name] for f in dataclasses.fields(cls)))


# --------------------------------------------------------------------------- policy


def actor_mean(policy: Any, obs: Any) -> Any:
    """The mean action of an SB3 ``ActorCriticPolicy`` for a batch of (normalised)
    observations, with gradients: what ``predict(deterministic=True)`` returns, unclipped."""
    features = policy.extract_features(obs, policy.pi_features_extractor)
    return policy.action_net(policy.mlp_extractor.forward_actor(features))


def actor_parameters(policy: Any) -> list[Any]:
    """The parameters of the actor: its features extractor, policy branch and action head."""
    modules = (policy.pi_features_extractor, policy.mlp_extractor.policy_net, policy.action_net)
    return [p for module in modules for p in module.parameters()]


def fit(
    policy: Any,
    optimizer: Any,
    obs: np.ndarray,
    actions: np.ndarray,
    epochs: int,
    batch_size: int,
    generator: Any,
    stop: Callable[[], bool] | None = None,
    weight: np.ndarray | None = None,
    rate: Callable[[int, int], float] | None = None,
) -> float:
    """Regress the actor's mean action on ``actions`` (MSE) for ``epochs`` passes over
    ``obs`` (already normalised); returns the last epoch's mean loss. ``weight``: each
    sample's weight in the loss (default 1); ``rate(epoch, step)``: the learning rate of
    each optimiser step (default: the optimiser's own)."""
    import torch

    x = torch.as_tensor(obs, dtype=torch.float32)
    y = torch.as_tensor(actions, dtype=torch.float32)
    w = None if weight is None else torch.as_tensor(weight, dtype=torch.float32)
    policy.set_training_mode(True)
    loss_value = float("nan")
    try:
        for epoch in range(epochs):
            order = torch.randperm(len(x), generator=generator)
            total = 0.0
            for step, begin in enumerate(range(0, len(x), batch_size)):
                if rate is not None:
                    for group in optimizer.param_groups:
                        group["lr"] = rate(epoch, step)
                index = order[begin : begin + batch_size]
                mean = actor_mean(policy, x[index])
                if w is None:
                    loss = torch.nn.functional.mse_loss(mean, y[index])
                else:
                    loss = ((mean - y[index]).square().mean(1) * w[index]).mean()
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                total += loss.item() * len(index)
            loss_value = total / len(x)
            if stop is not None and stop():
                break
    finally:
        policy.set_training_mode(False)
    return loss_value


def make_normalizer(env_factory: Callable[[], Any], obs: np.ndarray) -> Any:
    """An SB3 ``VecNormalize`` (observations only, ``training=False``) whose statistics
    are those of ``obs``; it wraps a one-environment ``DummyVecEnv`` of ``env_factory``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    normalizer = VecNormalize(DummyVecEnv([env_factory]), norm_obs=True, norm_reward=False)
    set_statistics(normalizer, obs)
    return normalizer


def set_statistics(normalizer: Any, obs: np.ndarray) -> None:
    """Set ``normalizer``'s observation statistics to those of ``obs`` and freeze them."""
    data = np.asarray(obs, np.float64)
    normalizer.obs_rms.mean = data.mean(axis=0)
    normalizer.obs_rms.var = np.maximum(data.var(axis=0), OBS_VAR_FLOOR)
    normalizer.obs_rms.count = float(len(data))
    normalizer.training = False


def save_normalizer(normalizer: Any, path: Path) -> None:
    """Pickle ``normalizer``'s statistics alone (its environments are not pickled)."""
    venv, normalizer.venv = normalizer.venv, None
    try:
        with open(path, "wb") as stream:
            pickle.dump(normalizer, stream)
    finally:
        normalizer.venv = venv


# --------------------------------------------------------------------------- settings


ACTIVATIONS: tuple[str, ...] = ("tanh", "relu")
"""The hidden layers' activation a recipe may name (``policy_kwargs["activation_fn"]``)."""


def torch_policy_kwargs(policy_kwargs: dict[str, Any]) -> dict[str, Any]:
    """SB3's ``policy_kwargs`` for a recipe's: the activation's name becomes its class."""
    import torch

    kwargs = copy.deepcopy(policy_kwargs)
    name = kwargs.pop("activation_fn", "tanh")
    kwargs["activation_fn"] = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}[name]
    return kwargs


def _check_net_arch(policy_kwargs: Any) -> dict[str, Any]:
    if not isinstance(policy_kwargs, dict):
        raise ArgumentTypeError(
            f"policy_kwargs must be a dict (e.g. {{'net_arch': [256, 256]}}); got {policy_kwargs!r}."
        )
    arch = policy_kwargs.get("net_arch", [64, 64])
    if (
        not isinstance(arch, (list, tuple))
        or not arch
        or any(isinstance(u, bool) or not isinstance(u, int) or u < 1 for u in arch)
    ):
        raise ValueError(
            "policy_kwargs['net_arch'] must be a non-empty list of layer widths >= 1 (the "
            f"actor and the value branch each get it), e.g. [256, 256]; got {arch!r}."
        )
    activation = policy_kwargs.get("activation_fn", "tanh")
    if activation not in ACTIVATIONS:
        raise ValueError(
            f"policy_kwargs['activation_fn'] must be one of {', '.join(ACTIVATIONS)}; got "
            f"{activation!r}."
        )
    unknown = sorted(set(policy_kwargs) - {"net_arch", "activation_fn"})
    if unknown:
        raise ValueError(
            f"policy_kwargs takes net_arch and activation_fn; got also {unknown}. Remove them."
        )
    return policy_kwargs


def check_settings(algo: str, settings: dict[str, Any]) -> dict[str, Any]:
    """Check (and normalise) the numbers of a bc/dagger recipe; ValueError naming the key."""
    check_run_numbers(algo, settings)
    settings["algo"]["policy_kwargs"] = _check_net_arch(settings["algo"]["policy_kwargs"])
    return settings


# --------------------------------------------------------------------------- trainer


def train_imitation(
    algo: str,
    task: str,
    out: str | os.PathLike[str],
    seed: int = 0,
    eval_episodes: int | None = None,
    hyperparams: dict[str, Any] | None = None,
    env: Mapping[str, Any] | None = None,
    device: str = "cpu",
) -> Any:
    """Train ``algo`` (``"bc"`` or ``"dagger"``) on ``task`` from its expert and write the
    policy folder (see the module's documentation). With camera observations in ``env``
    (``obs_type="pixels_agent_pos"``) the student learns from pixels
    (:mod:`gym_soarm.rl.pixels`).

    Every argument is checked before anything is built or written.

    Args:
        algo: ``"bc"`` or ``"dagger"``.
        task: a registered task (its name, alias or id).
        out: the output folder (created; files of an earlier run there are replaced).
        seed: the training seed (the network, the noise, the training resets).
        eval_episodes: validation episodes (seeds 50000 + k) per evaluation (default: the recipe's).
        hyperparams: values that replace the recipe's ``algo`` keys (``{"demos": 20}``).
        env: ``gym.make`` keywords over the recipe's environment (see
            :func:`gym_soarm.rl.training.train`).
        device: where a pixel student trains (``"cpu"``, ``"cuda"``, ``"cuda:1"``);
            state policies train on the CPU.

    Returns:
        A :class:`gym_soarm.rl.training.TrainResult` (``env_steps``: the environment
        steps of the training episodes).

    Raises:
        ValueError: unknown algorithm or task, a bad number, ``out`` a file.
        ImportError: Stable-Baselines3 is not installed (names the extra).
    """

    if algo not in IMITATION:
        raise ValueError(
            f"train_imitation trains {', '.join(IMITATION)}; got {algo!r} (PPO and SAC: "
            "gym_soarm.rl.training.train)."
        )
    spec = get_task(task)  # ValueError naming the registered tasks
    pixels = is_pixel_env(env or {})
    looks = (env or {}).get("visual_randomization", "none")
    settings = pixel_recipe(algo, spec.name, looks) if pixels else recipe(algo, spec.name)
    settings["env"] = merge_keywords(settings["env"], spec.name, env)
    if pixels:
        check_pixel_student(spec, settings["env"])
    check_device(device, pixels)
    seed = check_int("seed", seed, 0)
    if eval_episodes is not None:
        settings["eval_episodes"] = eval_episodes
    override(settings, hyperparams, algo)
    settings = check_pixel_settings(algo, settings) if pixels else check_settings(algo, settings)
    out_path = Path(out)
    if out_path.exists() and not out_path.is_dir():
        raise ValueError(f"out must be a folder; {str(out_path)!r} is a file. Pass a new folder.")
    require_sb3()
    pyplot()
    if pixels:
        if looks != "none" and "demos" not in (hyperparams or {}):
            floor = pixel_recipe(algo, spec.name)["algo"]["demos"]
            demos_within_store(algo, spec, settings, floor)
        store_bound(algo, spec, settings)  # a ValueError before the folder is made
    folder = RunFolder(out_path, "").prepare(
        (MODEL_FILE, NORMALIZE_FILE, DEMOS_FILE, PIXEL_MODEL_FILE)
    )
    trainer_class = PixelTrainer if pixels else StateTrainer
    with folder:
        return trainer_class(algo, spec, folder, seed, settings, device).run()


class StateTrainer(ImitationTrainer):
    """A state student (an SB3 ``MlpPolicy`` actor) of the task's state expert: the
    DAgger loop of :class:`ImitationTrainer <gym_soarm.rl.dagger.ImitationTrainer>` with
    the folder of the module's documentation."""

    rng_stream = 22

    def setup(self) -> None:
        import torch

        torch.set_num_threads(self.settings["torch_threads"])
        self.generator = torch.Generator().manual_seed(self.seed)
        kind = "BC" if self.algo == "bc" else "DAgger"
        self.title = f"{kind} on {self.spec.name}, seed {self.seed}"
        self.data: Dataset | None = None
        self._new: list[Dataset] = []
        self.normalizer: Any = None
        self.model_env: Any = None
        self.model: Any = None
        self.optimizer: Any = None

    def run(self) -> TrainResult:
        try:
            return super().run()
        finally:
            if self.model_env is not None:
                self.model_env.close()

    def make_vector_env(self) -> Any:
        venv = super().make_vector_env()
        obs_dim, act_dim = len(self.observation_names), venv.single_action_space.shape[0]
        self.data = Dataset.empty(obs_dim, act_dim)
        return venv

    def dataset(self) -> Dataset:
        """Every step stored (the steps of the last gathering joined once)."""
        for part in self._new:
            self.data = self.data.extend(part)
        self._new = []
        return self.data

    def stored(self) -> int:
        return len(self.data) + sum(len(part) for part in self._new)

    def record(
        self, run: Gathering, live: np.ndarray, labels: Any, executed: Any, round_: int
    ) -> None:
        obs = np.asarray(run.obs, np.float32)[live]
        rounds = np.full(len(obs), round_, np.int64)
        self._new.append(Dataset(obs, labels[live], executed[live], run.episode[live], rounds))

    def normalized(self, obs: np.ndarray) -> np.ndarray:
        if self.normalizer is None:
            return np.asarray(obs, np.float32)
        return np.asarray(self.normalizer.normalize_obs(obs), np.float32)

    def learner(self, obs: np.ndarray) -> np.ndarray:
        return self.model.predict(self.normalized(obs), deterministic=True)[0]

    def student_actions(self, run: Gathering, mask: np.ndarray) -> np.ndarray:
        return np.asarray(self.learner(np.asarray(run.obs, np.float32)[mask]), np.float32)

    def start_learning(self) -> None:
        """The normaliser (statistics of the demonstrations) and the PPO model."""
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import DummyVecEnv

        name, kwargs = self.spec.name, self.env_kwargs

        def env_factory() -> Any:
            return make_env(name, kwargs)

        torch.manual_seed(self.seed)
        if self.settings["normalize"]:
            self.normalizer = make_normalizer(env_factory, self.dataset().obs)
            self.model_env = self.normalizer
        else:
            self.model_env = DummyVecEnv([env_factory])
        params = self.params
        self.model = PPO(
            "MlpPolicy", self.model_env, seed=self.seed, device="cpu", n_steps=64,
            batch_size=64, learning_rate=params["learning_rate"],
            policy_kwargs=torch_policy_kwargs(params["policy_kwargs"]),
        )  # fmt: skip
        self.optimizer = torch.optim.Adam(
            actor_parameters(self.model.policy), lr=params["learning_rate"]
        )

    def fit(self, epochs: int) -> float:
        data, params = self.dataset(), self.params
        rate = self.fit_rates(epochs, len(data))
        weight = episode_weights(data.episode, params) if params["episode_weighting"] else None
        return fit(
            self.model.policy, self.optimizer, self.normalized(data.obs), data.actions,
            epochs, params["batch_size"], self.generator, self.stop, weight, rate,
        )  # fmt: skip

    def save(self) -> None:
        """The model and its observation statistics (the data: :meth:`after_evaluation`)."""
        if self.model is None:
            return
        self.model.save(self.out_path / MODEL_FILE)
        if self.normalizer is not None:
            save_normalizer(self.normalizer, self.out_path / NORMALIZE_FILE)

    def after_evaluation(self) -> None:
        self.dataset().save(self.out_path / DEMOS_FILE)

    def on_interrupt(self) -> None:
        if self.model is None and self.stored():
            self.start_learning()
        if not (self.out_path / MODEL_FILE).exists():  # else the best round's stays
            self.save()
        if self.model is not None:
            self.after_evaluation()
            self.write_settings()
        self.folder.write_curve()


def check_device(device: Any, pixels: bool) -> None:
    """A ValueError unless ``device`` is a torch device name this trainer can use."""
    if not isinstance(device, str) or not (
        device == "cpu" or device == "cuda" or (device.startswith("cuda:") and device[5:].isdigit())
    ):
        raise ValueError(f"device must be 'cpu', 'cuda' or 'cuda:N'; got {device!r}.")
    if device != "cpu" and not pixels:
        raise ValueError(
            f"device {device!r}: state policies train on the CPU (their networks are small); "
            "a GPU serves pixel students (--obs-type pixels_agent_pos). Drop --device."
        )


def check_pixel_student(spec: Any, env_kwargs: Mapping[str, Any]) -> None:
    """A ValueError unless a pixel student can learn ``spec`` with ``env_kwargs``: camera
    images beside ``agent_pos``, and a state expert to label its states."""
    obs_type = env_kwargs.get("obs_type")
    if obs_type not in PIXEL_OBS_TYPES:
        raise ValueError(
            f"a pixel student learns from obs_type {' or '.join(PIXEL_OBS_TYPES)} (the cameras "
            f"and the measured joints); got {obs_type!r}. Pass --obs-type pixels_agent_pos."
        )
    for key, wanted in (
        ("control_mode", "joint_pos"),
        ("normalize_actions", True),
        ("units", "radians"),
    ):
        got = env_kwargs.get(key, wanted)
        if got != wanted:
            raise ValueError(
                f"a pixel student acts with {key}={wanted!r} (normalised absolute joint targets "
                f"in radians, its own last command among its inputs); got {key}={got!r}. Drop "
                f"--{key.replace('_', '-')}."
            )
    if spec.state_expert is None:
        raise ValueError(
            f"a pixel student is taught by its task's state expert; {spec.name} has none (only "
            "a timed script). Give the task a state expert (TaskSpec.state_expert), or train "
            "from the state vector."
        )


__all__ = [
    "DEMOS_FILE",
    "Dataset",
    "StateTrainer",
    "actor_mean",
    "fit",
    "train_imitation",
    "training_seeds",
]
