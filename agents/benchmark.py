"""The score of a policy on a named task (``drillgym benchmark``): the task's protocol on its held-out plants.

A policy is a classical controller (a name :func:`controllers.available` lists, or ``NAME@MS``) or a learned
one (``agent:PATH``); several learned policies (``agent:`` paths, e.g. the seeds of one recipe) are scored
one by one and aggregated over the seeds with the IQM and its stratified-bootstrap 95 % interval
(:mod:`.benchmark_stats`).  Runs go through the controllers' evaluation harness
(:func:`controllers.evaluation.evaluate`), the plants of a population task are the task's held-out list.
With ``model=`` (``drillgym benchmark TASK --model FILE``) the policies are scored on that model's plant
alone (its base parameters and effects; the classical controllers are built on its base parameters, its
effects hidden from them, as a task's plants are), with the task's sensors, targets and run length: a
score of the policy on that rig, not the task's score.

    >>> from agents.benchmark import BenchmarkOptions, run_benchmark
    >>> res = run_benchmark("drillgym/Population-Motor-v0", ["descent"])
    >>> res.scores[0].p90, res.aggregates["p90"].iqm
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drillgym.envs.tasks import BenchmarkTask, get_task
from drillgym.errors import InputError, MissingFileError

from .benchmark_stats import Aggregate, iqm_interval

__all__ = ["BenchmarkOptions", "PolicyScore", "BenchmarkResult", "resolve_policies", "run_benchmark", "METRICS"]

#: the aggregated metrics of a policy seed (:class:`PolicyScore` fields)
METRICS = ("median", "p90", "ssi", "whirl", "energy")


@dataclass(frozen=True)
class BenchmarkOptions:
    """Reductions of the task's protocol (for quick checks; a reduced score is marked as such).

    Parameters
    ----------
    plants : int, optional
        The first ``plants`` of the held-out list (plant k does not depend on the list's length);
        default the whole list.
    duration, window : float, optional
        Run length and steady window (s); default the protocol's.
    targets : tuple of float, optional
        Target grid (rad/s); default the protocol's.
    workers : int, optional
        Processes of the harness (1: this process).
    progress : bool, optional
        Show the harness's progress bar.
    identified_dir : str or path, optional
        On an ``Identified`` task: the folder of the held-out plants' identifications
        (``plant_<k>/model.json`` and ``identification.json``, :func:`controllers.evaluation.identify.save_identified`);
        the plants it holds are read back, the others identified and written there, so a second policy is scored
        without identifying again.  Default: identified in memory, nothing kept.
    """

    plants: int | None = None
    duration: float | None = None
    window: float | None = None
    targets: tuple[float, ...] | None = None
    workers: int = 1
    progress: bool = False
    identified_dir: str | Path | None = None

    def settings(self, task: BenchmarkTask) -> dict:
        """The settings of a run: plants, targets, duration, window, seed."""
        p, pr = task.plants, task.protocol
        if self.plants is not None and not p.population:
            raise InputError(f"--plants applies to a population task; {task.id} runs the identified rig only")
        n = p.eval_plants if self.plants is None else int(self.plants)
        if p.population and not (1 <= n <= p.eval_plants):
            raise InputError(f"--plants must be in 1..{p.eval_plants} (the held-out list of {task.id}), got {n}")
        return {
            "plants": n if p.population else 1,
            "targets": tuple(pr.targets if self.targets is None else self.targets),
            "duration": float(pr.duration if self.duration is None else self.duration),
            "window": float(pr.window if self.window is None else self.window),
            "seed": p.eval_seed,
        }

    def reduced(self, task: BenchmarkTask) -> bool:
        """True when any setting differs from the task's protocol."""
        s, pr = self.settings(task), task.protocol
        full_plants = task.plants.eval_plants if task.plants.population else 1
        return (s["plants"], s["targets"], s["duration"], s["window"]) != (
            full_plants,
            pr.targets,
            pr.duration,
            pr.window,
        )


@dataclass(frozen=True)
class PolicyScore:
    """The score of one policy (one seed) on a task.

    Parameters
    ----------
    policy : str
        The controller spec (name, ``NAME@MS`` or ``agent:PATH``).
    plant_lowest : tuple of float
        Each held-out plant's lowest held target (rad/s; inf: not even the highest target held).
    median, p90 : float
        Median and 90th percentile of ``plant_lowest`` (rad/s; ``numpy.quantile(method="higher")``).
    ssi : float
        Median stick-slip severity over all runs (plants x targets; dimensionless).
    whirl : float
        Median whirl over all runs (95th percentile of the lower disc's lateral displacement over the steady
        window / the 20 mm stop, :class:`drillgym.envs.tasks.EvaluationProtocol`; dimensionless, 0 on a
        torsional task).
    energy : float
        Mean motor work of a run over all runs (J per run of the protocol's duration).
    none_held : int
        Plants holding no target.
    runaway : int
        Plants on which a run passed the rig's over-speed stop (40 rad/s).
    whirl_limited : int
        Plants whose lowest held target the whirl criterion raised (a coupled task's targets held on speed
        and SSI but whirling past the protocol's ``whirl_threshold``); 0 on a torsional task.
    """

    policy: str
    plant_lowest: tuple[float, ...]
    median: float
    p90: float
    ssi: float
    energy: float
    none_held: int
    runaway: int
    whirl: float = 0.0
    whirl_limited: int = 0

    def to_json(self) -> dict:
        """The score as JSON-ready values (inf: a plant holding nothing; written as null with a warning)."""
        return {
            "policy": self.policy,
            "plant_lowest": list(self.plant_lowest),
            "median": self.median,
            "p90": self.p90,
            "ssi": self.ssi,
            "whirl": self.whirl,
            "energy": self.energy,
            "none_held": self.none_held,
            "runaway": self.runaway,
            "whirl_limited": self.whirl_limited,
        }


@dataclass(frozen=True)
class BenchmarkResult:
    """A policy's score on a task: one :class:`PolicyScore` per seed and their aggregates.

    Parameters
    ----------
    task : str
        The task id.
    scores : tuple of PolicyScore
        One per policy seed.
    aggregates : dict of str to Aggregate
        Per metric of :data:`METRICS`: IQM and stratified-bootstrap 95 % interval over the seeds.
    settings : dict
        The protocol as run: plants, targets (rad/s), duration and window (s), seed.
    reduced : bool
        True when the settings differ from the task's protocol (not the task's score).
    """

    task: str
    scores: tuple[PolicyScore, ...]
    aggregates: dict[str, Aggregate] = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    reduced: bool = False

    def to_json(self) -> dict:
        """The result as JSON-ready values; inf (no target held) is written as null, the top-level
        ``warnings`` list naming it (:func:`drillgym.io.jsonfile.dumps_json`)."""
        return {
            "task": self.task,
            "reduced": self.reduced,
            "settings": {**self.settings, "targets": list(self.settings.get("targets", ()))},
            "scores": [s.to_json() for s in self.scores],
            "aggregates": {k: a.to_json() for k, a in self.aggregates.items()},
        }

    def lines(self) -> list[str]:
        """The result as printed lines: one per seed, then the IQM and interval per metric."""
        s = self.settings
        plants = f"the plant of model {s['model']['label']}" if "model" in s else f"{s['plants']} held-out plant(s)"
        head = (
            f"{self.task}: {plants}, targets {s['targets'][0]:g}-{s['targets'][-1]:g} rad/s "
            f"({len(s['targets'])}), {s['duration']:g} s runs judged over the last {s['window']:g} s"
        )
        if "identified" in s:
            head += f", each policy built on its plant's identified model ({s['identified']})"
        if "model" in s:
            out = [head + " (a model's plant: not the task's score)"]
        else:
            out = [head + (" (REDUCED protocol: not the task's score)" if self.reduced else "")]
        coupled = get_task(self.task).config == "coupled"
        for p in self.scores:
            whirl = f"whirl {p.whirl:.3g} (plants limited by it {p.whirl_limited}); " if coupled else ""
            out.append(
                f"  {p.policy}: lowest held target median {_speed(p.median)}, 90th pct {_speed(p.p90)}; "
                f"SSI {p.ssi:.3g}; {whirl}energy {p.energy:.3g} J/run; plants holding none {p.none_held}, "
                f"runaway {p.runaway}"
            )
        if len(self.scores) > 1:
            for m, a in self.aggregates.items():
                out.append(f"  IQM over {a.seeds} seeds, {m}: {_num(a.iqm)} [{_num(a.ci_low)}, {_num(a.ci_high)}] 95 %")
        return out


def _speed(v: float) -> str:
    return "none held" if math.isinf(v) else f"{v:.2f} rad/s"


def _num(v: float) -> str:
    return "inf" if math.isinf(v) else ("-" if math.isnan(v) else f"{v:.3g}")


def _seed_dirs(path: Path) -> dict[int, Path]:
    out = {}
    for d in path.iterdir() if path.is_dir() else ():
        m = re.fullmatch(r"seed_(\d+)", d.name)
        if m and d.is_dir():
            out[int(m.group(1))] = d
    return dict(sorted(out.items()))


def resolve_policies(specs: Sequence[str], seeds: Sequence[int] | None = None) -> list[str]:
    """The controller specs to score, one per policy seed.

    Parameters
    ----------
    specs : sequence of str
        Classical controller names (``NAME`` or ``NAME@MS``) or ``agent:PATH`` (a policy.npz, a run directory,
        or a directory of seeds ``seed_<s>/`` as ``drillgym train --seeds`` writes).  Several ``agent:`` specs
        are seeds of one policy.
    seeds : sequence of int, optional
        With one ``agent:DIR`` of seed directories: the seeds to score (default all of them).

    Returns
    -------
    list of str
        ``NAME``, ``NAME@MS`` or ``agent:PATH`` specs.

    Raises
    ------
    InputError
        No policy, a classical controller mixed with others, duplicates, or ``--seeds`` without a directory of
        seeds (or naming a seed it lacks).
    MissingFileError
        An ``agent:`` path that does not exist.
    """
    specs = [s.strip() for s in specs]
    if not specs or not all(specs):
        raise InputError("--policy: no policy given; a controller name (drillgym controllers) or agent:PATH")
    agents = [s for s in specs if s.startswith("agent:")]
    if agents and len(agents) != len(specs) or (not agents and len(specs) > 1):
        raise InputError("--policy: give one classical controller, or agent:PATH specs (the seeds of one policy)")
    if len(set(specs)) != len(specs):
        raise InputError(f"--policy: the same policy given twice ({', '.join(specs)})")
    if not agents:
        if seeds:
            raise InputError(f"--seeds applies to agent:DIR with seed_<s>/ directories; {specs[0]} is deterministic")
        return specs
    out = []
    for s in agents:
        path = Path(s[len("agent:") :])
        if not path.exists():
            raise MissingFileError(f"--policy {s}: {path} not found (a policy.npz, a run directory or seed_<s>/ dirs)")
        dirs = _seed_dirs(path)
        if seeds and not dirs:
            raise InputError(f"--seeds: {path} holds no seed_<s>/ directories")
        if dirs:
            chosen = list(seeds) if seeds else list(dirs)
            missing = [k for k in chosen if k not in dirs]
            if missing:
                raise InputError(f"--seeds: {path} has no seed_{missing[0]}/; it has seeds {', '.join(map(str, dirs))}")
            out += [f"agent:{dirs[k]}" for k in chosen]
        else:
            out.append(s)
    seen: dict[Path, str] = {}
    for s in out:  # one network named twice (a file and its run directory) would count as two seeds
        p = Path(s[len("agent:") :])
        key = ((p / "policy.npz" if (p / "policy.npz").is_file() else p / "model.zip") if p.is_dir() else p).resolve()
        if key in seen:
            raise InputError(f"--policy: {s} is the same network as {seen[key]}; give each seed once")
        seen[key] = s
    return out


def check_sensing(task: BenchmarkTask, spec: str) -> None:
    """Refuse a policy that reads more than the task's sensors (``Controller.uses`` against ``task.reads``)."""
    from controllers import make

    ctrl = make(spec, config=task.config, omega_ref=task.protocol.targets[-1])
    extra = [m for m in ctrl.uses if m not in task.reads]
    if extra:
        raise InputError(
            f"--policy {spec} reads {', '.join(extra)}, which task {task.id} does not measure (it gives "
            f"{', '.join(task.reads)})"
        )


def _score(task: BenchmarkTask, spec: str, rows: list[dict], population: bool | None = None) -> PolicyScore:
    from controllers.evaluation.metrics import lowest_free_speed
    from controllers.evaluation.population_report import plant_lowest

    sel = [r for r in rows if r["controller"] == spec]
    whirl = task.protocol.whirl_threshold if task.config == "coupled" else None
    pop = task.plants.population if population is None else population

    def lowest(threshold: float | None) -> list[float]:
        if pop:
            return list(plant_lowest(sel, spec, task.config, whirl_threshold=threshold).values())
        v = lowest_free_speed(
            np.array([r["omega_ref"] for r in sel]),
            np.array([r["ssi"] for r in sel]),
            offset=np.array([r["offset"] for r in sel]),
            whirl=None if threshold is None else np.array([r["whirl"] for r in sel]),
            whirl_threshold=threshold,
        )
        return [math.inf if math.isnan(v) else v]

    a = np.array(lowest(whirl), dtype=float)
    limited = int(np.sum(a > np.array(lowest(None), dtype=float))) if whirl is not None else 0
    run = {int(r["plant"]) if pop else 0 for r in sel if r["runaway"]}
    return PolicyScore(
        spec,
        tuple(float(v) for v in a),
        float(np.quantile(a, 0.5, method="higher")),
        float(np.quantile(a, 0.9, method="higher")),
        float(np.median([r["ssi"] for r in sel])),
        float(np.mean([r["energy"] for r in sel])),
        int(np.isinf(a).sum()),
        len(run),
        float(np.median([r["whirl"] if whirl is not None else r.get("whirl", 0.0) for r in sel])),
        limited,
    )


def run_benchmark(
    task_id: str, policies: Sequence[str], options: BenchmarkOptions | None = None, *, model=None
) -> BenchmarkResult:
    """Score policies (seeds of one policy, or one classical controller) on a named task.

    Parameters
    ----------
    task_id : str
        A task id (:data:`drillgym.envs.tasks.TASKS`).
    policies : sequence of str
        Resolved specs (:func:`resolve_policies`).
    options : BenchmarkOptions, optional
        Reductions of the protocol and the harness's workers; default the task's protocol.
    model : drillgym.Model, str or path, optional
        Score on this model's plant alone (see the module docstring) instead of the task's plants; a path is
        read without ``trust``.  Not with ``options.plants``.

    Returns
    -------
    BenchmarkResult
        Per seed the score, over the seeds the IQM and interval of each metric.

    Raises
    ------
    InputError
        An unknown task, a policy reading more than the task's sensors, or a bad setting.
    """
    from controllers.evaluation import evaluate

    task = get_task(task_id)
    opts = options or BenchmarkOptions()
    if model is not None:
        if opts.identified_dir is not None:
            raise InputError(
                "--identified picks the task's identified plants; with a model (--model) the run has that plant only"
            )
        return _run_on_model(task, policies, opts, model)
    st = opts.settings(task)
    for spec in policies:
        check_sensing(task, spec)
    if opts.identified_dir is not None:
        if not task.identified:
            raise InputError(f"--identified applies to an identified task (-Identified-v0); {task.id} is not one")
        if Path(opts.identified_dir).exists() and not Path(opts.identified_dir).is_dir():
            raise InputError(f"--identified {opts.identified_dir}: not a folder (the plants' identifications go there)")
    identified = None
    if task.identified:
        from .identified_plants import identified_plants

        identified = identified_plants(task, "held-out", st["plants"], opts.identified_dir, opts.workers, opts.progress)
        st["identified"] = str(opts.identified_dir) if opts.identified_dir is not None else "in memory"
    rows = evaluate(
        list(policies),
        [task.config],
        ["plants" if task.plants.population else "rest"],
        list(st["targets"]),
        duration=st["duration"],
        window=st["window"],
        workers=opts.workers,
        progress=opts.progress,
        plants=st["plants"],
        seed=st["seed"],
        uncertainty=None if task.plants.uncertainty == "default" else task.plants.uncertainty,
        identify=identified,
    )
    scores = tuple(_score(task, spec, rows) for spec in policies)
    agg = {m: iqm_interval([getattr(s, m) for s in scores]) for m in METRICS}
    return BenchmarkResult(task.id, scores, agg, st, opts.reduced(task))


def _run_on_model(task: BenchmarkTask, policies: Sequence[str], opts: BenchmarkOptions, model) -> BenchmarkResult:
    """The policies on one model's plant with the task's sensors, targets and run length (``run_benchmark``)."""
    from controllers.evaluation import evaluate
    from drillgym.model import as_model

    if opts.plants is not None:
        raise InputError(
            "--plants picks the task's held-out plants; with a model (--model) the run has that plant only"
        )
    m = as_model(model, who="benchmark: model")
    m.composition.refuse_not_acting(task.config, "the model's effects")
    st = BenchmarkOptions(None, opts.duration, opts.window, opts.targets).settings(task)
    st["plants"] = 1
    st["model"] = {"label": m.label, "params": m.params.to_dict(), "effects": m.records()}
    for spec in policies:
        check_sensing(task, spec)
    rows = evaluate(
        list(policies),
        [task.config],
        ["rest"],
        list(st["targets"]),
        duration=st["duration"],
        window=st["window"],
        params=m.params,
        effects=m.composition,
        effect_params=dict(m.values),
        workers=opts.workers,
        progress=opts.progress,
        seed=st["seed"],
    )
    scores = tuple(_score(task, spec, rows, population=False) for spec in policies)
    agg = {k: iqm_interval([getattr(sc, k) for sc in scores]) for k in METRICS}
    return BenchmarkResult(task.id, scores, agg, st, True)
