"""Kernel templates: the compiled code that depends on the composition of effects.

``model`` (right-hand side, friction, switching), ``stepping`` (event-driven RK steps, runs,
stepping of batches) and ``lanes`` (the SIMD lane kernel) import the composition's hooks
(:mod:`drillgym.kernels.hooks`, the interface).  They are never compiled here: for each
composition :mod:`drillgym.effects.codegen` writes specialised copies that import the
generated hooks (``drillgym.effects.compose(...)[0].kernels``).
"""
