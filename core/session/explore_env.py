"""Exploring one object as a Gymnasium environment (``palpate/Explore-v0``, docs/gym.md).

An episode explores one object of a scenario on a 2-D map, as :func:`~palpate.core.session.explore.explore_object`
does, except that the agent picks every cell. Each step presses the chosen cell, fuses the press into the map,
post-processes it, and rewards what the press bought. Gymnasium is the ``gym`` extra: only this module imports it,
and ``import palpate`` never loads this module.

Presses come from one of two press models:

- ``"sim"``: the scenario's registered source (``training.source``, the simulated finger of the ``sim`` extra),
  perceived as a run perceives them;
- ``"offline"`` (default, for learning): a press on a cell whose true material is t draws its fitted parameters
  [n1, n2, a1, a2] from the memory's Gaussians of t, the same draws :mod:`~palpate.core.planning.outcomes` plans
  with. Thousands of presses a second; the memory is still trained on simulated presses (or given).

Reward ("accuracy", default): the gain in the fraction of the object's cells the post-processed map labels
right; summed over an episode it is the final accuracy minus the accuracy of the untouched map. Reward
("entropy"): the fall of the post-processed map's mean cell entropy (map's base units). Terminated when the
post-processed map meets the scenario's entropy stop rule (``stop_mean_entropy`` / ``stop_max_entropy``; when the
scenario sets neither, mean entropy <= ``stop_mean_entropy`` given here); truncated after ``budget`` presses.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.extras import require_extra

try:
    import gymnasium as gym
    from gymnasium import spaces
    from gymnasium.vector.utils import iterate
except ModuleNotFoundError:  # said as the extra to install, by name
    require_extra("the Gymnasium environment", "gymnasium")
    raise
from palpate.core.mapping.accuracy import map_accuracy
from palpate.core.mapping.grids import new_map
from palpate.core.mapping.probability import entropy_unchecked
from palpate.core.perception.press import perceive_press
from palpate.core.planning.registry import stop_reason
from palpate.core.session.explore import MapPostprocessing, apply_press
from palpate.core.session.progress import Progress
from palpate.core.session.sources import PressTarget, scenario_source_maker
from palpate.core.world.scenario import Scenario
from palpate.core.world.workspace import ground_truth_map, object_geometry

ENV_ID = "palpate/Explore-v0"
DEFAULT_SCENARIO = "explore_info_gain"
PRESS_MODELS = ("offline", "sim")
REWARDS = ("accuracy", "entropy")
#: Length of the observation's ``features``: the fitted [n1, n2, a1, a2] of the last press.
N_FEATURES = 4


def _scenario(scenario: str | Path | Scenario) -> Scenario:
    if isinstance(scenario, Scenario):
        return scenario
    from palpate.api import load_scenario

    return load_scenario(scenario)


def train_env_memory(scenario: str | Path | Scenario = DEFAULT_SCENARIO, source: str | None = None):
    """The haptic memory an environment judges presses with: the scenario's training presses from its source
    (``sim``). Train it once and pass it to every environment of a vector (``memory=``)."""
    from palpate.core.session.training import train_memory, training_seeds

    sc = _scenario(scenario)
    make = scenario_source_maker(sc, source or sc.training.source)
    return train_memory(sc, make, training_seeds(sc), Progress(enabled=False)).memory


class ExploreEnv(gym.Env):
    """Press cells of one object's map until it is known (see the module docstring for reward and termination).

    Observation (a Dict):
        probabilities: (ny, nx, M) float32, the post-processed map's P(material) per cell (M reference materials);
        explored: (ny, nx) int8, 1 where a press landed;
        features: (4,) float32, the last press's fitted [n1, n2, a1, a2] (c_P in counts, c_D in mm, c_A in mm^2),
            zeros before the first press and after a press with no fit.
    Action: Discrete(nx * ny), the cell ix + nx * iy (0-based).
    Info: k (presses so far), cell (ix, iy), accuracy (post-processed map, None without truth), mean_entropy,
        stop ("budget", "mean_entropy", "max_entropy" or None).

    Args:
        scenario: a shipped name, a .toml path or a Scenario (2-D map).
        object: which object to explore (default: the first).
        press_model: "offline" or "sim".
        reward: "accuracy" or "entropy".
        budget: presses per episode (default: the scenario's exploration budget).
        stop_mean_entropy: the stop rule when the scenario has none (map's base units).
        memory: a trained HapticMemory (default: trained on the scenario's source at construction).
        source_maker: ``make(objects, seed, variability)`` of the simulated press model's sources (default:
            :func:`~palpate.core.session.sources.scenario_source_maker` of the scenario, made once, so that what its
            sources solve, such as contact laws, serves every later episode); a vector shares one among its
            environments.
    """

    metadata = {"render_modes": []}

    def __init__(self, scenario: str | Path | Scenario = DEFAULT_SCENARIO, object: str | None = None,
                 press_model: str = "offline", reward: str = "accuracy", budget: int | None = None,
                 stop_mean_entropy: float = 0.05, memory=None, render_mode: str | None = None, source_maker=None):
        if press_model not in PRESS_MODELS:
            raise ValidationError(f"press_model must be one of {', '.join(PRESS_MODELS)}, got {press_model!r}")
        if reward not in REWARDS:
            raise ValidationError(f"reward must be one of {', '.join(REWARDS)}, got {reward!r}")
        if render_mode is not None:
            raise ValidationError(f"render_mode: this environment renders nothing, got {render_mode!r} (use None)")
        self.scenario = sc = _scenario(scenario)
        entries = {e.spec.name: e for e in sc.objects}
        if object is not None and object not in entries:
            raise ValidationError(f"object {object!r} is not in {sc.name}; its objects: {', '.join(entries)}")
        self.entry = entries[object] if object is not None else sc.objects[0]
        ex = sc.exploration
        self.geometry = object_geometry(sc, self.entry)
        if self.geometry.voxel:
            raise ValidationError(f"{sc.name}: exploration.map = {ex.map!r}; the environment explores 2-D maps "
                                  "(exploration.map = \"grid2d\")")
        self.budget = ex.budget if budget is None else budget
        if isinstance(self.budget, bool) or not isinstance(self.budget, int) or self.budget < 1:
            raise ValidationError(f"budget must be an integer >= 1 (presses), got {self.budget!r}")
        self.press_model, self.reward_kind = press_model, reward
        self.render_mode = None
        self.memory = memory if memory is not None else train_env_memory(sc)
        if getattr(self.memory, "means_N", None) is None:
            raise ValidationError("memory: the environment needs a trained HapticMemory (palpate.train_memory)")
        self._stop = ({"mean_entropy": ex.stop_mean_entropy, "max_entropy": ex.stop_max_entropy}
                      if ex.stop_mean_entropy is not None or ex.stop_max_entropy is not None
                      else {"mean_entropy": stop_mean_entropy})
        self.truth = ground_truth_map(self.entry, sc, self.geometry)
        self._centres = self.geometry.cell_centres()  # (ny, nx, 2), m
        self._post_settings = MapPostprocessing.of(ex)
        nx, ny = self.geometry.plane_shape
        m = len(self.geometry.materials)
        self.observation_space = spaces.Dict({
            "probabilities": spaces.Box(0.0, 1.0, (ny, nx, m), np.float32),
            "explored": spaces.MultiBinary((ny, nx)),
            "features": spaces.Box(-np.inf, np.inf, (N_FEATURES,), np.float32),
        })
        self.action_space = spaces.Discrete(nx * ny)
        self._grid = self._post = self._plan = self._source = None
        if source_maker is not None and not callable(source_maker):
            raise ValidationError(f"source_maker must be callable as make(objects, seed, variability), got "
                                  f"{type(source_maker).__name__}")
        self._make_source = source_maker
        self._features = np.zeros(N_FEATURES, np.float32)
        self._k = 0
        self._given = None  # a press made for this environment by its vector (give_press)

    # -- what the agent sees -------------------------------------------------------------------------------------
    def _obs(self) -> dict:
        return {"probabilities": np.clip(self._post.probabilities, 0.0, 1.0).astype(np.float32),
                "explored": np.asarray(self._grid.explored, dtype=np.int8),
                "features": self._features.copy()}

    def _score(self) -> float:
        if self.reward_kind == "accuracy":
            acc = map_accuracy(self._post.probabilities, self.truth)
            return 0.0 if acc is None else float(acc)
        return -float(entropy_unchecked(np.asarray(self._plan.probabilities), self._plan.base).mean())

    def _info(self, cell=None, stop=None) -> dict:
        return {"k": self._k, "cell": cell, "accuracy": map_accuracy(self._post.probabilities, self.truth),
                "mean_entropy": float(self._post.mean_entropy()), "stop": stop}

    def _postprocess(self) -> None:
        cal = self.scenario.exploration.calibration
        self._post = self._post_settings.apply(self._grid, cal)
        self._plan = self._post_settings.planned_on(self._grid, cal, self._post)

    # -- the Gymnasium API ---------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start a new exploration of the object: an empty map (and, with ``press_model="sim"``, a new source seeded
        from ``seed``). Returns the observation (``probabilities``, ``explored``, ``features``) and the info dict."""
        super().reset(seed=seed)
        self._grid = new_map(self.geometry)
        self._features = np.zeros(N_FEATURES, np.float32)
        self._k = 0
        self._given = None
        if self.press_model == "sim":
            if self._make_source is None:
                self._make_source = scenario_source_maker(self.scenario, self.scenario.training.source)
            self._source = self._make_source((self.entry.spec,), int(self.np_random.integers(2**31)),
                                             self.scenario.exploration.variability)
        self._postprocess()
        return self._obs(), self._info()

    def step(self, action):
        """Press the cell ``action`` (index ``iy * nx + ix``) and fuse what it read. Returns (observation, reward:
        the change of the map's score, terminated: a stop rule fired, truncated: the budget is spent, info).
        Raises ValidationError before :meth:`reset` or on an action outside the map."""
        if self._grid is None:
            raise ValidationError("step before reset: call env.reset(seed=...) first")
        if not self.action_space.contains(action):
            raise ValidationError(f"action must be a cell index in [0, {self.action_space.n}), got {action!r}")
        ix, iy, x, y = self._cell(action)
        before = self._score()
        params = (self._press_offline(ix, iy, x, y) if self.press_model == "offline"
                  else self._press_sim(int(action), x, y))
        self._features = (np.zeros(N_FEATURES, np.float32) if params is None
                          else np.asarray(params[:N_FEATURES], dtype=np.float32))
        self._k += 1
        self._postprocess()
        reward = self._score() - before
        stop = stop_reason(self._plan, **self._stop)
        truncated = stop is None and self._k >= self.budget
        return self._obs(), float(reward), stop is not None, truncated, \
            self._info((ix, iy), stop or ("budget" if truncated else None))

    def _press_offline(self, ix: int, iy: int, x: float, y: float) -> np.ndarray | None:
        """Draw the press's parameters from the memory's Gaussians of the cell's true material and fuse its
        posterior; a cell with no true material (off the object) gives no press."""
        t = int(self.truth[iy, ix])
        if t < 0:
            return None
        mem = self.memory
        params = np.concatenate([self.np_random.multivariate_normal(mem.means_N[t], mem.covs_N[t]),
                                 self.np_random.multivariate_normal(mem.means_A[t], mem.covs_A[t])])
        p = mem.predict_proba(params[None, :])[0]
        self._grid.update(x, y, self.scenario.exploration.calibration.evidence(p))
        return params

    def _cell(self, action) -> tuple[int, int, float, float]:
        """(ix, iy, x m, y m) of the cell an action names."""
        nx = self.geometry.plane_shape[0]
        ix, iy = int(action) % nx, int(action) // nx
        x, y = (float(v) for v in self._centres[iy, ix])
        return ix, iy, x, y

    def _target(self, x: float, y: float) -> PressTarget:
        ex = self.scenario.exploration
        return PressTarget(x, y, depth=ex.depth, force=ex.max_force, speed=ex.speed,
                           label=f"{self.entry.spec.name} gym")

    def planned_press(self, action) -> tuple[object, PressTarget] | None:
        """(source, target) of the simulated press ``step(action)`` would make, for a vector that presses its
        environments' sources in one batch and hands each its recording (:meth:`give_press`); None with the offline
        press model, before :meth:`reset`, or for an action off the map (``step`` then says why)."""
        if self.press_model != "sim" or self._source is None or not self.action_space.contains(action):
            return None
        _, _, x, y = self._cell(action)
        return self._source, self._target(x, y)

    def give_press(self, action, recording) -> None:
        """The recording of the press :meth:`planned_press` planned for ``action``, made by its source outside the
        environment; the next ``step(action)`` perceives it instead of pressing again."""
        self._given = (int(action), recording)

    def _press_sim(self, action: int, x: float, y: float) -> np.ndarray | None:
        given, self._given = self._given, None
        rec = given[1] if given is not None and given[0] == action else self._source.press(self._target(x, y))
        res = perceive_press(rec).at_target((x, y))
        apply_press(self._grid, res, self.memory, None, fallback_xy=(x, y),
                    calibration=self.scenario.exploration.calibration)
        return None if res.fit is None else np.asarray(res.fit.params, dtype=float)


class ExploreVectorEnv(gym.vector.SyncVectorEnv):
    """Environments stepped together, as gymnasium's SyncVectorEnv steps them, except that with the simulated press
    model the presses of one vector step are made in one batch (the source's ``press_across``, e.g. palpate's
    simulated source: every analytic press's physics in one vectorised call). Each environment's source presses in
    the order a loop would, so every observation, reward and info equals SyncVectorEnv's."""

    def step(self, actions):
        """Press every stepping environment's cell (one batch), then step each as SyncVectorEnv does."""
        acts = list(iterate(self.action_space, actions))
        # which environments this step resets rather than steps: SyncVectorEnv's own record (gymnasium >= 1.0)
        resetting = getattr(self, "_autoreset_envs", np.zeros(self.num_envs, bool))
        next_step = getattr(getattr(self, "autoreset_mode", None), "name", "NEXT_STEP") == "NEXT_STEP"
        planned = []
        for i, (env, action) in enumerate(zip(self.envs, acts, strict=True)):
            if next_step and resetting[i]:
                continue  # this step resets the environment instead of pressing
            plan = env.unwrapped.planned_press(action) if hasattr(env.unwrapped, "planned_press") else None
            if plan is not None:
                planned.append((env.unwrapped, action, plan))
        batch = getattr(planned[0][2][0], "press_across", None) if planned else None
        if batch is not None and all(getattr(p[0], "press_across", None) == batch for _, _, p in planned):
            for (env, action, _), rec in zip(planned, batch([p for _, _, p in planned]), strict=True):
                env.give_press(action, rec)
        return super().step(actions)


def make_vector_env(num_envs: int, scenario: str | Path | Scenario = DEFAULT_SCENARIO, **kwargs):
    """``num_envs`` environments stepped together (:class:`ExploreVectorEnv`: with the simulated press model, one
    batch of presses a step), sharing one memory trained once; ``autoreset_mode`` (gymnasium's ``AutoresetMode``)
    goes to the vector, every other keyword to each environment."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise ValidationError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    sc = _scenario(scenario)
    memory = kwargs.pop("memory", None)
    if memory is None:
        memory = train_env_memory(sc)
    if kwargs.get("press_model") == "sim" and kwargs.get("source_maker") is None:
        kwargs["source_maker"] = scenario_source_maker(sc, sc.training.source)  # one law cache for the vector
    # gymnasium hands a custom vector every argument in one set: the vector's own are taken out here
    vector = {k: kwargs.pop(k) for k in ("autoreset_mode",) if k in kwargs}
    return ExploreVectorEnv([lambda: ExploreEnv(sc, memory=memory, **kwargs) for _ in range(num_envs)], **vector)


def register() -> None:
    """Register ``palpate/Explore-v0`` with gymnasium (again is harmless)."""
    if ENV_ID not in gym.registry:
        gym.register(ENV_ID, entry_point="palpate.core.session.explore_env:ExploreEnv",
                     vector_entry_point="palpate.core.session.explore_env:make_vector_env")
