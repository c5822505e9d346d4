"""What ``drillgym rig`` does around an episode: dry run, e-stop, reconnect, and telling the operator.

* :func:`dry_run` checks everything a run needs (port and firmware handshake, control period,
  controller or policy, limits, recording path) without sending a voltage.
* :func:`emergency_stop` sends EMERGENCY_STOP and waits for the firmware's ACK.
* :func:`run_with_reconnect` runs the episode; after a lost link or a firmware that stopped
  answering it reopens the port and starts a new episode (a new recording), as often as allowed.
* :func:`stop_reason` and :class:`ClampNotice` are the one-line messages of a stop and of a
  voltage clamped to the amplifier range (said once).

Exit codes of ``rig run``: 0 episode completed; 2 bad option or file (nothing moved);
3 safety stop (watchdog, over-speed, e-stop, link fault: the motor is at 0 V, the recording kept);
130 interrupted (Ctrl-C or SIGTERM: motor at 0 V, recording kept).
"""

from __future__ import annotations

import os
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

from drillgym.errors import InputError

__all__ = [
    "STOP_EXIT",
    "INTERRUPT_EXIT",
    "stop_reason",
    "ClampNotice",
    "dry_run",
    "emergency_stop",
    "run_with_reconnect",
    "check_writable",
]

STOP_EXIT = 3
INTERRUPT_EXIT = 130

_WHY = {
    "WATCHDOG": "the firmware's watchdog stopped the motor: no command for {watchdog_ms} ms (host stalled or "
    "too slow; see the README's hardware section)",
    "OVERSPEED": "over-speed: a disc turned faster than the limit",
    "OVER_DISPLACEMENT": "over-displacement: the lower disc moved laterally beyond the limit",
    "HOST": "emergency stop requested by a host (e.g. `drillgym rig estop`)",
    "LINK_LOST": "the firmware saw the link go down",
    "FIRMWARE": "the firmware reports the motor stopped",
}


def stop_reason(stop: str | None, watchdog_ms: float, terminated: bool) -> str | None:
    """The one-line reason an episode ended early.

    Parameters
    ----------
    stop : str or None
        The safety stop the firmware or the host reported (``"WATCHDOG"``, ``"OVERSPEED"``, ...).
    watchdog_ms : float
        The firmware's watchdog (ms), named in the watchdog's reason.
    terminated : bool
        The episode ended on the task's safety limit.

    Returns
    -------
    str or None
        The reason, or None when the episode ran its course.
    """
    if stop is not None:
        return f"{stop}: " + _WHY.get(stop, "stop").format(watchdog_ms=f"{watchdog_ms:g}")
    if terminated:
        return "the task's safety limit (speed or lateral displacement beyond the episode's limits)"
    return None


class ClampNotice:
    """Tell the operator, once, that a command beyond the amplifier range was clamped; count how often.

    The ``on_step`` callback of :func:`hw.runner.run_episode`.

    Parameters
    ----------
    echo : callable
        Prints one line for the operator.
    v_max : float, optional
        The amplifier range (V). Default 5.

    Attributes
    ----------
    count : int
        Commands clamped so far.
    """

    def __init__(self, echo: Callable[[str], None], v_max: float = 5.0) -> None:
        self.echo, self.v_max, self.count = echo, v_max, 0

    def __call__(self, step: int, info: dict) -> None:
        if "clamped_from" in info:
            self.count += 1
            if self.count == 1:
                self.echo(
                    f"note: {info['clamped_from']:g} V asked for at step {step}; the amplifier gives "
                    f"+-{self.v_max:g} V, so commands beyond it are clamped to +-{self.v_max:g} V "
                    f"(said once; counted at the end)"
                )


def check_writable(record: Path) -> None:
    """Refuse a recording path that could not be written; nothing is created (:func:`hw.checks.check_record_path`).

    Parameters
    ----------
    record : pathlib.Path
        The recording file (``.csv``) or directory.

    Raises
    ------
    OutputPathError
        A directory, device, pipe or socket where a .csv file is named, a file where a directory is named, a path
        under a file or where nothing can be created (``/proc``, no permission).
    """
    from hw.checks import check_record_path

    check_record_path(record, "--record")


def dry_run(make_env: Callable[[], object], ctrl, policy, record: Path, echo: Callable[[str], None]) -> None:
    """Check everything a run needs without sending a voltage.

    Opens the port, identifies the firmware and checks the policy against the observation space;
    the port is closed with EMERGENCY_STOP, as always (the next run's handshake clears it).

    Parameters
    ----------
    make_env : callable
        Builds the hardware environment (opens the port).
    ctrl : Controller or None
        The controller, when no policy is given.
    policy : callable or None
        The policy (observation to action).
    record : pathlib.Path
        The recording path the run would write.
    echo : callable
        Prints one line for the operator.

    Raises
    ------
    InputError
        The recording path is not writable, or the policy's action is unusable.
    """
    import numpy as np

    from drillgym.envs.action import action_voltage

    check_writable(record)
    env = make_env()
    try:
        u = env.unwrapped
        fw, lim = u.firmware, u.limits
        echo(
            f"dry run: {u.port}: firmware {fw.name!r}, protocol {fw.protocol_version}, control period "
            f"{fw.period_s * 1e3:g} ms accepted, watchdog {fw.watchdog_ms} ms"
        )
        echo(
            f"dry run: limits host / firmware: +-{lim.v_max:g} / +-{fw.v_max:g} V, slew {lim.slew_v_per_s:g} / "
            f"{fw.slew_v_per_s:g} V/s, over-speed {lim.max_speed:g} / {fw.max_speed:g} rad/s, over-displacement "
            f"{lim.max_displacement * 1e3:g} / {fw.max_displacement * 1e3:g} mm"
        )
        if policy is not None:
            a = policy(np.zeros(env.observation_space.shape, dtype=np.float32))
            try:
                action_voltage(a, float(env.action_space.high[0]))
            except (TypeError, ValueError) as exc:
                raise InputError(f"the policy's action for a zero observation is unusable: {exc}") from None
            echo(f"dry run: policy answers a zero observation of shape {env.observation_space.shape} with {a!r}")
        else:
            echo(f"dry run: controller {getattr(ctrl, 'name', type(ctrl).__name__)} ready")
            volts = getattr(ctrl, "volts", None)
            if volts is not None and abs(volts) > lim.v_max:
                echo(f"note: {volts:g} V will be clamped to +-{lim.v_max:g} V (the amplifier range)")
        echo(f"dry run: recording would go to {record}; nothing was sent that moves the motor")
    finally:
        env.close()


def emergency_stop(port: str, attempts: int = 3, timeout_s: float = 0.2) -> int:
    """Send EMERGENCY_STOP (HOST) until the firmware acknowledges it.

    Parameters
    ----------
    port : str
        Serial device or pyserial URL of the rig.
    attempts : int, optional
        Sends at most. Default 3.
    timeout_s : float, optional
        Wait for each acknowledgement (s). Default 0.2.

    Returns
    -------
    int
        The attempt that was acknowledged (1-based).

    Raises
    ------
    SafetyError
        No acknowledgement came (another program may be reading the port, or the firmware is dead).
    """
    from drillgym.errors import SafetyError
    from hw.client import RigClient
    from hw.link import LinkTimeoutError

    client = RigClient(port, reply_timeout=timeout_s)
    try:
        return client.emergency_stop(wait=True, attempts=attempts)
    except LinkTimeoutError:
        raise SafetyError(
            f"{port}: EMERGENCY_STOP sent {attempts} times, no acknowledgement within "
            f"{timeout_s * 1e3:.0f} ms each (another program reading the port may have taken it, or "
            f"the firmware is not responding): check the rig"
        ) from None
    finally:
        client.close()


def _wait_for_port(port: str, seconds: float) -> None:
    """Sleep ``seconds``, and on until the device path exists again (at most 10 s more)."""
    time.sleep(seconds)
    t_end = time.monotonic() + 10.0
    while "://" not in port and not os.path.exists(port) and time.monotonic() < t_end:
        time.sleep(0.1)


def run_with_reconnect(env, run: Callable[[], object], reconnect: int, wait_s: float, echo: Callable[[str], None]):
    """Run one episode; after a lost link or a silent firmware, reopen the port and run a new one.

    Parameters
    ----------
    env : gymnasium.Env
        The hardware environment (its port is waited for before reconnecting).
    run : callable
        Runs one episode and returns its result.
    reconnect : int
        New episodes allowed after link faults.
    wait_s : float
        Wait before reconnecting (s).
    echo : callable
        Prints one line for the operator.

    Returns
    -------
    result : object
        What the last ``run()`` returned.
    faults : list of str
        The link faults that were recovered from.

    Raises
    ------
    hw.link.LinkLostError, hw.link.LinkTimeoutError
        A link fault after ``reconnect`` reconnections.
    """
    from hw.link import LinkLostError, LinkTimeoutError

    faults: list[str] = []
    while True:
        try:
            return run(), faults
        except (LinkLostError, LinkTimeoutError) as exc:
            if len(faults) >= reconnect:
                raise
            faults.append(str(exc))
            echo(f"drillgym: link fault ({exc}); reconnecting in {wait_s:g} s ({len(faults)} of {reconnect})")
            _wait_for_port(env.unwrapped.port, wait_s)


def trained_agent(path: Path) -> bool:
    """Whether a path is what ``drillgym train`` writes.

    Parameters
    ----------
    path : pathlib.Path
        A run directory, a ``model.zip``, or a ``.npz`` file.

    Returns
    -------
    bool
        True for a run directory, its ``model.zip`` or an exported ``policy.npz`` with its
        metadata; False for a bare linear ``.npz`` (arrays W, b).

    Raises
    ------
    InputError
        If a ``.npz`` file is not an archive numpy reads (``--policy`` named in one line).
    """
    import numpy as np

    p = Path(path)
    if p.is_dir() or p.suffix == ".zip":
        return True
    if p.suffix == ".npz" and p.is_file():
        try:
            z = np.load(p, allow_pickle=False)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            from hw.runner import npz_problem

            raise InputError(
                f"--policy {p}: not a policy file (numpy could not read it: {npz_problem(exc)}); give a .npz written "
                "by drillgym train, a linear policy (arrays W and b) or a training run's directory"
            ) from None
        if not hasattr(z, "files"):  # a single .npy array: the linear policy's loader names what it needs
            return False
        with z:
            return "meta" in z.files
    return False


def warm_up(ctrl, omega_ref: float | None, dt: float) -> None:
    """Reset the controller and let it act a few times on a rig at rest, before the port is opened.

    Its compiled parts (e.g. a trained agent's observation model) load now, not inside the
    firmware's watchdog.

    Parameters
    ----------
    ctrl : Controller
        The controller.
    omega_ref : float or None
        Target lower-disc speed (rad/s); None uses 4 rad/s.
    dt : float
        Control period (s).
    """
    m = {
        "t": 0.0,
        "theta_u": 0.0,
        "theta_l": 0.0,
        "x": 0.0,
        "y": 0.0,
        "omega_ref": 4.0 if omega_ref is None else float(omega_ref),
    }
    ctrl.reset(m)
    for k in (1, 2, 3):  # the first act answers the reset; the later ones read the encoder too
        ctrl.act({**m, "t": k * dt})
