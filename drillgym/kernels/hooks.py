"""The hooks through which a composition of effects enters the kernel templates.

This file documents the interface; it is never compiled.  For every composition of
effects :mod:`drillgym.effects.codegen` writes a module with these names (the effects'
functions inlined into them) and a specialised copy of each kernel template that imports
it in place of this one.  The empty composition (the base model) goes through exactly the
same generator.

Constants
    N_EFFECT_STATES   number of continuous states the effects add (after the 8 mechanical ones)
    N_STATE           8 + N_EFFECT_STATES
    N_OUT             number of recorded columns (OUTPUT_NAMES of the composition)
    HAS_DELAY         True when a Delay effect is present
    HAS_LATERAL_FORCE True when a Force effect acts on the lower disc's centre
    HAS_LAG           True when an Input effect declares first-order lag states (integrated exactly)

Scalar kernel (state vector y, parameter vector p)
    hk_rhs(t, u, y, p, cfg, dy) -> (volt, Qu, Ql, Qs, Qx, Qy)
        the voltage at the motor (V) after the Input effects, extra torques on the upper and
        lower discs and in the string (N m), extra generalised lateral forces (N, rotating
        frame); writes the effects' state derivatives into dy[8:].
    hk_slip_u(T, d, aw, t, y, p, brake) / hk_slip_l(...) -> slip torque (N m)
    hk_bounds_u(lo, hi, t, y, p, brake) / hk_bounds_l(...) -> (lo, hi) stick set (N m)
    hk_delay(p) -> transport delay of the command (s)
    hk_lag(t, u, y, p, cfg, h, yo): the declared lag states (Input.lag) at h after a step started at
        (t, y) with command u, exactly, into yo[8 + j] (HAS_LAG: the composition declares some)

Lane kernel (lane k; mechanical scalars, lane state rows Y (nm mechanical rows first),
parameter rows PT (n_params, B))
    hk_rhs_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg) -> as hk_rhs (no writes)
    hk_states_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg, K): the effects' state
        derivatives into K[nm + j, k] (called in a loop of its own)
    hk_slip_u_lane(T, d, aw, k, t, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, brake) / ..._l_lane
    hk_lag_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg, h, Yo): as hk_lag, lane k,
        from the start rows Y into Yo[nm + j, k]
    hk_bounds_u_lane(lo, hi, k, t, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, brake) / ..._l_lane

Measurement
    hk_measure(theta_u, theta_l, X, Y, p) -> (theta_u, theta_l, X, Y) as the sensors read them
"""

raise ImportError("drillgym.kernels.hooks is the interface description; kernels are built per composition "
                  "by drillgym.effects.codegen (use drillgym.effects.compose(...).kernels)")
