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
    N_PARAMS          number of parameters (base, then the effects')
    N_SWITCHES        number of effects that declare where they vanish (Parameter.neutral)
    HAS_LANE_EFFECTS  True when an Input, Force or Friction effect is present (hk_effects_lane has work)

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
    hk_lag_start(t, u, y, p, cfg): the lag states left NaN (not given at the start) set to the steady
        state of the first command u held before the start (the history the delay lines assume)

Lane kernel (lanes as structure of arrays: lane state rows Y (nm mechanical rows first), parameter
rows PT (N_PARAMS + N_SWITCHES, B))
    hk_lane_params(P) -> PT: P (B, N_PARAMS) transposed, then one switch row per effect that declares
        where it vanishes (Parameter.neutral): 1.0 in every lane when any lane's parameters of that
        effect leave their neutral values, else 0.0
    hk_effects_lane(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, nm, MU, ML, U, PT, TT, tc, cfg, brake, E):
        every effect on every lane, one loop per effect with its switch tested outside the loop (an
        effect switched off costs nothing; small loops stay vectorised).  In: the mechanical rows
        (zeros for absent lateral coordinates), the modes MU, ML, the command U, step start times TT
        and stage offset tc, and in E[6], E[7] the base laws' slip torques.  Out: E[0] the voltage at
        the motor, E[1:4] Qu, Ql, Qs, E[4:6] Qx, Qy (rotating frame), E[6], E[7] the slip torques with
        the friction effects (0 for a stuck disc); E[8], E[9] work (friction levels)
    hk_states_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg, K): the effects' state
        derivatives into K[nm + j, k] (called in a loop of its own)
    hk_lag_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg, h, Yo): as hk_lag, lane k,
        from the start rows Y into Yo[nm + j, k]
    hk_bounds_u_lane(lo, hi, k, t, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, brake) / ..._l_lane

Measurement
    hk_measure(theta_u, theta_l, X, Y, omega_u, omega_l, p) -> (theta_u, theta_l, X, Y) as the sensors read
    them (the speeds in rad/s: a reading may depend on the direction of motion)
"""

raise ImportError(
    "drillgym.kernels.hooks is the interface description; kernels are built per composition "
    "by drillgym.effects.codegen (use drillgym.effects.compose(...).kernels)"
)
