"""Kernel templates: the compiled code that depends on the composition of effects.

``model`` (right-hand side, friction, switching), ``commands`` (command tables, transport-delay
line), ``stepping`` (event-driven RK steps, fixed-step runs, stepping of batches), ``adaptive``
(Dormand-Prince 5(4) runs), ``lane_steps`` and ``lanes`` (the SIMD lane kernel) import the
composition's hooks (:mod:`drillgym.kernels.hooks`, the interface).  They are never compiled here: for each
composition :mod:`drillgym.effects.codegen` writes specialised copies that import the
generated hooks (``drillgym.effects.compose(...)[0].kernels``).
"""
