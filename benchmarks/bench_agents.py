"""The kept agent: inference time and its row of the controller table (harness, from rest).

    .venv/bin/python benchmarks/bench_agents.py [--policy agents/policies/torsional_motor_residual_observer/policy.npz]
                                                [--workers 2] [--skip-table]

Prints (1) the time of one control step: the numpy policy alone and the whole
``AgentController.act`` (measurement -> observation -> policy -> volts), batch of one,
beside SB3's ``predict`` on the same model (best of 5 x 2000 calls); (2) the harness table
(torsional and coupled, targets 0.5-8 rad/s, 60 s from rest, last 20 s) with the baseline,
the soft-torque controller and the agent's policy structure alone (residual 0: the start-up schedule of
the ``residual`` agents, the ``observer`` controller itself for agents on the observer base)
beside the agent; (3) SSI and tracking RMS per target with the brake friction 20 % below and above
the training value (torsional), agent and structure alone.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

import agents
from controllers.evaluation import DEFAULT_TARGETS, evaluate
from controllers.evaluation.report import markdown_table


def best_time(fn, calls: int = 2000, repeats: int = 5) -> float:
    """Best mean time per call (s)."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, (time.perf_counter() - t0) / calls)
    return best


def inference(policy_path: Path) -> None:
    policy = agents.load_policy(policy_path)
    obs = np.zeros(policy.obs_dim, dtype=np.float32)
    obs[-1] = 3.0
    ctrl = agents.load_controller(str(policy_path), config="torsional", omega_ref=3.0)
    ctrl.reset({"t": 0.0, "theta_u": 0.0})
    th = iter(np.cumsum(np.full(10_000_000, 0.03)))
    print(f"numpy policy act():              {1e6 * best_time(lambda: policy.act(obs)):8.1f} us per step")
    t_all = best_time(lambda: ctrl.act({"t": 0.0, "theta_u": next(th)}))
    print(f"AgentController.act() (all):     {1e6 * t_all:8.1f} us per step")
    model_zip = policy_path.with_name("model.zip")
    if model_zip.is_file():
        from agents.train import algo_class

        model = algo_class(policy.config["algo"]).load(model_zip, device="cpu")
        t_sb3 = best_time(lambda: model.predict(obs, deterministic=True), 500)
        print(f"SB3 predict (torch, reference):  {1e6 * t_sb3:8.1f} us per step")


def zero_residual(policy_path: Path, directory: Path) -> Path:
    """The same policy file with the last layer zeroed: the residual structure alone (a = 0)."""
    with np.load(policy_path) as z:
        arrays = dict(z)
    n = len(json.loads(str(arrays["meta"]))["activations"])
    arrays[f"W{n - 1}"][:] = 0.0
    arrays[f"b{n - 1}"][:] = 0.0
    out = directory / "structure_only.npz"
    np.savez(out, **arrays)
    return out


def table(policy_path: Path, workers: int) -> None:
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        names = {
            f"agent:{policy_path}": f"agent ({policy_path.parent.name})",
            f"agent:{zero_residual(policy_path, Path(d))}": "structure alone (residual 0)",
        }
        rows = evaluate(
            ["baseline", "softtorque", *names],
            ["torsional", "coupled"],
            ["rest"],
            DEFAULT_TARGETS,
            workers=workers,
            progress=False,
        )
        text = markdown_table(rows, "rest")
        for k, v in names.items():
            text = text.replace(k, v)
        print(text)
        rob = evaluate(
            list(names),
            ["torsional"],
            ["rest", "friction-20", "friction+20"],
            DEFAULT_TARGETS,
            workers=workers,
            progress=False,
        )
    print("torsional, per target (rad/s): SSI / tracking RMS (rad/s) over the last 20 s")
    print("                                          " + " ".join(f"{w:5.1f}" for w in DEFAULT_TARGETS))
    for key, label in names.items():
        for sc in ("rest", "friction-20", "friction+20"):
            sel = [r for r in rob if r["scenario"] == sc and r["controller"] == key]
            ssi = " ".join(f"{r['ssi']:5.2f}" if np.isfinite(r["ssi"]) else "  inf" for r in sel)
            rms = " ".join(f"{r['tracking_rms']:5.2f}" for r in sel)
            print(f"{label[:28]:28s} {sc:11s} SSI {ssi}")
            print(f"{'':28s} {sc:11s} RMS {rms}")
    print(f"({time.perf_counter() - t0:.0f} s wall)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--policy", type=Path, default=agents.KEPT_POLICY)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--skip-table", action="store_true")
    a = ap.parse_args()
    inference(a.policy)
    if not a.skip_table:
        table(a.policy, a.workers)


if __name__ == "__main__":
    main()
