"""Layouts shared by the episode machinery and its compiled period kernel."""

#: columns of ``EpisodeBatch.S`` (per-rig episode quantities); the first ones are the info entries
INFO_COLUMNS = ("voltage", "omega_ref", "reward", "stick_slip_severity", "omega_l", "friction_torque", "stuck", "time")
S_COLUMNS = INFO_COLUMNS + ("steps", "terminated", "truncated")
C_U, C_REF, C_REW, C_SSI, C_WL, C_TFL, C_STUCK, C_TIME, C_STEPS, C_TERM, C_TRUNC = range(len(S_COLUMNS))
#: values of the ``terminated`` column: running, a safety limit (speed, lateral displacement), a non-finite state
TERM_NONE, TERM_LIMIT, TERM_NONFINITE = 0.0, 1.0, 2.0
# layout of the task vector ``tv`` (constants of the period kernel)
T_W, T_SPEED, T_LAT, T_LATERAL, T_STEPS, T_BLOCK, T_DT, T_FULL, T_BOUNDS = 0, 4, 5, 6, 7, 8, 9, 10, 11
