"""Hardware twin: the rig's serial protocol, the host environment ``drillgym/Hardware-v0``, the
safety layer, episode recording, and an emulator of the rig's microcontroller.

Modules: :mod:`hw.protocol` (frames, messages, parser; hw/PROTOCOL.md), :mod:`hw.crc`,
:mod:`hw.link` (pyserial transport, link errors), :mod:`hw.client` (host protocol client),
:mod:`hw.safety`, :mod:`hw.processing`, :mod:`hw.measurements` (a SAMPLE to the env's readings,
state and observation), :mod:`hw.pacing`, :mod:`hw.recording`, :mod:`hw.env` (:class:`HardwareEnv`),
:mod:`hw.firmware` and :mod:`hw.emulator` (the emulated microcontroller on a pseudo-terminal).
"""

ENV_ID = "drillgym/Hardware-v0"


def register() -> None:
    """Register ``drillgym/Hardware-v0`` with Gymnasium (if not yet registered)."""
    import gymnasium

    if ENV_ID not in gymnasium.registry:
        gymnasium.register(id=ENV_ID, entry_point="hw.env:HardwareEnv", disable_env_checker=True)
