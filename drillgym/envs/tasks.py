"""Named benchmark tasks: fixed environment options, fixed plants and a fixed evaluation protocol.

A task (as a CARL environment family) is one rig configuration, one set of sensors and one
distribution of plants, the plant's physical parameters being the context.  ``Nominal`` tasks run the
identified rig; ``Population`` tasks draw each training episode's rig from a fixed list of plants of
the documented uncertainty set (``controllers/evaluation/plants.yaml``) and are scored on a DISJOINT
fixed list of held-out plants of the same set.  Plant k of a list with seed s is the draw of the random
stream ``numpy.random.default_rng([s, k])`` (:func:`controllers.evaluation.population.sample_plants`), so
the training list (seed :attr:`PlantSet.train_seed`) and the held-out list (seed
:attr:`PlantSet.eval_seed`) share no stream, and both are the same in every process.

    >>> import gymnasium, drillgym
    >>> env = gymnasium.make("drillgym/Population-Motor-v0")   # a training env of the task
    >>> drillgym.envs.tasks.TASKS["drillgym/Population-Motor-v0"].protocol.duration
    60.0

The score of a policy on a task is measured by ``drillgym benchmark TASK --policy SPEC`` (the
controllers' evaluation harness on the held-out plants, see ``docs/benchmark.md``).  This module holds
the definitions only (data and the per-episode draw of a listed plant); the plant lists are drawn
outside the physics core, by the env entry point ``agents.benchmark_env``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = [
    "SENSORS",
    "PlantSet",
    "EvaluationProtocol",
    "BenchmarkTask",
    "TASKS",
    "get_task",
    "PlantListRandomizer",
    "FREE_OPTIONS",
]

#: sensing of a task -> (env observation mode, the measurements a controller may read)
SENSORS = {
    "motor": ("motor", ("t", "theta_u", "omega_ref")),
    "two-encoder": ("sensors", ("t", "theta_u", "theta_l", "omega_ref")),
    "sensors": ("sensors", ("t", "theta_u", "theta_l", "x", "y", "omega_ref")),
}

#: environment options a user may still set on a task id: how a policy builds its observation, the reward
#: it learns from and rendering (they change neither the rig, the plants, the sensors nor the score)
FREE_OPTIONS = ("render_mode", "render_history", "motor_history", "velocity_filter_tau", "reward", "ssi_window")


@dataclass(frozen=True)
class PlantSet:
    """The plants of a task.

    Parameters
    ----------
    population : bool
        False: the identified (nominal) rig only.  True: plants drawn from ``uncertainty``.
    uncertainty : str, optional
        The uncertainty set: ``"default"`` (``controllers/evaluation/plants.yaml``) or a YAML path.
    train_seed : int, optional
        Seed of the training list: plant k is the draw of stream ``[train_seed, k]``.
    train_plants : int, optional
        Length of the training list; each training episode runs one of them, drawn uniformly.
    eval_seed : int, optional
        Seed of the held-out list (and of the measurement noise of the evaluation); must differ from
        ``train_seed``.
    eval_plants : int, optional
        Length of the held-out list the score is measured on.
    """

    population: bool
    uncertainty: str = "default"
    train_seed: int = 1
    train_plants: int = 1000
    eval_seed: int = 0
    eval_plants: int = 20

    def __post_init__(self) -> None:
        for name in ("train_seed", "train_plants", "eval_seed", "eval_plants"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < (1 if name.endswith("plants") else 0):
                raise InputError(f"plant set {name} must be an integer >= 0 (plants >= 1), got {v!r}")
        if self.population and self.train_seed == self.eval_seed:
            raise InputError(f"plant set: train_seed and eval_seed must differ (both {self.train_seed})")

    def train_streams(self) -> tuple[tuple[int, int], ...]:
        """The random streams ``(seed, k)`` of the training plants (empty for the nominal rig)."""
        return tuple((self.train_seed, k) for k in range(self.train_plants)) if self.population else ()

    def eval_streams(self) -> tuple[tuple[int, int], ...]:
        """The random streams ``(seed, k)`` of the held-out plants (empty for the nominal rig)."""
        return tuple((self.eval_seed, k) for k in range(self.eval_plants)) if self.population else ()


#: the evaluation grid of target speeds (rad/s): 0.5 to 8.0 in steps of 0.5 (the harness's default)
EVAL_TARGETS = tuple(float(v) for v in np.round(np.arange(0.5, 8.0 + 1e-9, 0.5), 3))


@dataclass(frozen=True)
class EvaluationProtocol:
    """How a policy is scored on a task (the controllers' evaluation harness).

    Every held-out plant runs every target from rest for ``duration`` seconds; a target is held when,
    over the last ``window`` seconds, the stick-slip severity is below 0.1 and the mean lower-disc speed
    is within 10 % of the target and, on a rig whose lower disc moves laterally (``coupled``), its whirl
    is below ``whirl_threshold``.  A plant's *lowest held target* is the lowest target of the grid from
    which every higher target is held (inf: not even the highest).  The score is its median and its
    90th percentile over the plants (``numpy.quantile(method="higher")``: a value some plant reached).

    The *whirl* of a run is the 95th percentile of the lateral displacement r = sqrt(x² + y²) of the lower
    disc's centre over the steady window, divided by the rig's lateral over-displacement stop (20 mm,
    ``hw.safety.SafetyLimits.max_displacement``, the env's ``max_lateral``): dimensionless, 1 when the disc
    reaches the stop (``controllers.evaluation.metrics.run_metrics``).  The mass unbalance alone makes a
    steady rotation whirl (0.072, 1.45 mm, at 8 rad/s on the identified rig, up to 0.079 on the held-out
    plants); the threshold is about twice that, so a target is lost to it only when the policy shakes the disc
    laterally beyond what the unbalance gives (``docs/benchmark.md``).

    Parameters
    ----------
    targets : tuple of float, optional
        Target speeds of the lower disc (rad/s).  Default 0.5 to 8.0 in steps of 0.5.
    duration : float, optional
        Length of each run from rest (s).  Default 60.
    window : float, optional
        Steady-state window at the end of each run (s).  Default 20.
    whirl_threshold : float, optional
        Whirl (dimensionless, see above) from which a target of a ``coupled`` task is not held.  Default
        0.15 (r = 3 mm at the 95th percentile).  Not applied on a ``torsional`` task (the disc is clamped
        laterally there, its whirl is 0).
    """

    targets: tuple[float, ...] = EVAL_TARGETS
    duration: float = 60.0
    window: float = 20.0
    whirl_threshold: float = 0.15

    def __post_init__(self) -> None:
        t = tuple(float(v) for v in self.targets)
        if not t or not all(math.isfinite(v) and v > 0 for v in t):
            raise InputError(f"protocol targets must be positive finite speeds (rad/s), got {self.targets!r}")
        object.__setattr__(self, "targets", tuple(sorted(t)))
        if not (0 < self.window < self.duration):
            raise InputError(f"protocol window ({self.window} s) must be in (0, duration = {self.duration} s)")
        w = self.whirl_threshold
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not (math.isfinite(w) and w > 0):
            raise InputError(f"protocol whirl_threshold must be a positive finite number, got {w!r}")


@dataclass(frozen=True)
class BenchmarkTask:
    """Hold the lower disc at a target speed without stick-slip, on a fixed rig (or plant population),
    seeing only fixed sensors.

    A named, registered Gymnasium id (``gymnasium.make(task.id)``) whose options are fixed: the spaces,
    reward and episode end are those of :class:`drillgym.envs.DrillEnv` with :meth:`env_options`.

    Parameters
    ----------
    id : str
        The Gymnasium id, ``drillgym/<Rig>-<Sensors>-v0`` (``-Identified-v0``: an identified task).
    config : str
        Rig configuration: ``"torsional"`` or ``"coupled"``.
    sensors : str
        ``"motor"`` (the motor encoder only), ``"two-encoder"`` (motor and lower encoders, torsional) or
        ``"sensors"`` (both encoders and the LVDTs, coupled); see :data:`SENSORS`.
    plants : PlantSet
        The nominal rig, or the training and held-out plant lists of the uncertainty set.
    episode_duration : float, optional
        Length of a training episode (s), the protocol's run length.  Default 60.
    protocol : EvaluationProtocol, optional
        How the score is measured.
    identified : bool, optional
        An ``Identified`` task (population only): before it is scored, each held-out plant gets the
        excitation run and identification the classical identify-then-control uses
        (``drillgym evaluate --identify``), and the policy is built on that plant's identified model
        (``controllers.make(spec, model=...)``: a model-based controller, or a learned policy on such a base,
        uses the model; a plain network does not read it).  Its env and training plants are the population
        task's.  Default False.

    Notes
    -----
    **Action space.** ``Box(-1, 1, (1,), float32)``, the motor voltage / 5 V.

    **Observation space.** ``"motor"`` sensing: the env's ``"motor"`` observation (the last H motor-encoder
    speed increments and voltages, then the target; H = ``motor_history``, default 16, 2H + 1 entries).
    ``"two-encoder"`` and ``"sensors"``: the env's ``"sensors"`` observation (torsional 7 entries: encoder
    angles, winding, filtered speeds, last voltage, target; coupled 9 with the LVDTs).

    **Reward.** That of :class:`drillgym.envs.DrillEnv` (tracking, stuck, effort, rate); the score is not
    the return but the lowest held target of :class:`EvaluationProtocol`.

    **Starting state.** Rest, initial winding U(-1, 1) rad; the target drawn per episode in the protocol's
    range (0.5 to 8 rad/s); on a population task the rig drawn per episode from the training list
    (:class:`PlantListRandomizer`).  The training env's encoder is the rig's (8000 counts, no angle
    noise); the held-out plants also draw their encoders (2048-8000 counts, angle noise up to 0.5 mrad).

    **Episode end.** As :class:`drillgym.envs.DrillEnv`: over-speed (30 rad/s), lateral displacement
    (coupled, 20 mm) or a non-finite state terminate; truncated after ``episode_duration`` (60 s).

    **Arguments.** ``gymnasium.make(task.id, **options)`` accepts only :data:`FREE_OPTIONS` (observation
    history, speed filter, reward weights, rendering); any other option is fixed by the task and refused.
    ``model=`` (a :class:`drillgym.Model` or a model file's path) is the task's NOMINAL model: a ``Nominal``
    task runs it (its base parameters and effects, in place of the identified rig); a ``Population`` task
    draws its training plants around it (the uncertainty set's relative ranges scale the model's base
    parameters, the set's effect parameters are drawn from their ranges, the model's other effect parameters
    keep their values), so ``model=`` never means one single plant there.  ``drillgym benchmark TASK
    --model FILE`` instead scores a policy on that model's plant alone.
    """

    id: str
    config: str
    sensors: str
    plants: PlantSet
    episode_duration: float = 60.0
    protocol: EvaluationProtocol = field(default_factory=EvaluationProtocol)
    identified: bool = False

    def __post_init__(self) -> None:
        if self.identified and not self.plants.population:
            raise InputError(f"task {self.id}: an identified task needs a population of plants")
        if self.sensors not in SENSORS:
            raise InputError(f"task {self.id}: sensors must be one of {', '.join(SENSORS)}, got {self.sensors!r}")
        if self.config not in ("torsional", "coupled"):
            raise InputError(f"task {self.id}: config must be torsional or coupled, got {self.config!r}")

    @property
    def observation(self) -> str:
        """The env's observation mode of this task's sensors."""
        return SENSORS[self.sensors][0]

    @property
    def reads(self) -> tuple[str, ...]:
        """The measurements (:data:`controllers.base.MEASUREMENTS` names) a policy of this task may read."""
        return SENSORS[self.sensors][1]

    def env_options(self, **free) -> dict:
        """The options of the task's env: fixed ones, plus any of :data:`FREE_OPTIONS` given.

        Parameters
        ----------
        **free
            Options of :data:`FREE_OPTIONS`.

        Returns
        -------
        dict
            Keywords of :class:`drillgym.envs.DrillEnv` (``configuration``, ``observation``, ...).

        Raises
        ------
        InputError
            An option the task fixes.
        """
        fixed = sorted(k for k in free if k not in FREE_OPTIONS)
        if fixed:
            raise InputError(
                f"task {self.id} fixes option {fixed[0]!r}; it accepts only {', '.join(FREE_OPTIONS)} "
                f"(use drillgym/{self.config.capitalize()}-v0 for free options)"
            )
        t = self.protocol.targets
        return {
            "configuration": self.config,
            "observation": self.observation,
            "normalize_action": True,
            "omega_ref_range": (t[0], t[-1]),
            "episode_duration": float(self.episode_duration),
            **free,
        }


def _tasks() -> dict[str, BenchmarkTask]:
    out = {}
    for cfg, prefix, sensed in (
        ("torsional", "", (("Motor", "motor"), ("TwoEncoder", "two-encoder"))),
        ("coupled", "Coupled-", (("Motor", "motor"), ("Sensors", "sensors"))),
    ):
        for rig, population in (("Nominal", False), ("Population", True)):
            for label, sensors in sensed:
                tid = f"drillgym/{prefix}{rig}-{label}-v0"
                out[tid] = BenchmarkTask(tid, cfg, sensors, PlantSet(population))
                if population:
                    tid = f"drillgym/{prefix}{rig}-{label}-Identified-v0"
                    out[tid] = BenchmarkTask(tid, cfg, sensors, PlantSet(population), identified=True)
    return out


#: every named task by id
TASKS: dict[str, BenchmarkTask] = _tasks()


def get_task(task_id: str) -> BenchmarkTask:
    """The task of a registered id.

    Parameters
    ----------
    task_id : str
        A key of :data:`TASKS` (the ``drillgym/`` prefix may be left out).

    Returns
    -------
    BenchmarkTask
        The task.

    Raises
    ------
    InputError
        An unknown id, naming the valid ones.
    """
    key = task_id if task_id.startswith("drillgym/") else f"drillgym/{task_id}"
    if key not in TASKS:
        raise InputError(f"unknown task {task_id!r}; choose from {', '.join(TASKS)}")
    return TASKS[key]


class PlantListRandomizer:
    """Each episode's rig drawn uniformly from a fixed list of plants (the env's randomizer role).

    Parameters
    ----------
    matrix : ndarray
        (n_plants, n_params) parameter vectors in the env's composition layout.
    """

    active = True

    def __init__(self, matrix: np.ndarray) -> None:
        m = np.array(matrix, dtype=np.float64, ndmin=2)
        if m.shape[0] < 1 or not np.all(np.isfinite(m)):
            raise InputError("a plant list needs at least one plant with finite parameters")
        self.matrix = m
        self.last_index = -1  # the list index of the last plant drawn (the env keeps it per rig: ``plant_index``)

    def sample(self, rng: np.random.Generator, omega_ref: float | None = None) -> np.ndarray:
        """One listed plant's parameter vector (``omega_ref`` unused)."""
        self.last_index = int(rng.integers(self.matrix.shape[0]))
        return self.matrix[self.last_index].copy()
