"""What any controller that sees only the motor angle can achieve: the near pole-zero cancellation.

About the slip equilibrium at lower speed ``omega`` the torsional rig is linear (docs/model.md,
deviations, alpha = theta_l - theta_u)::

    Ju d omega_u/dt = km u - b_u omega_u + k_theta alpha          (b_u = bu + dbu)
    d alpha/dt      = omega_l - omega_u
    Jl d omega_l/dt = -k_theta alpha - s(omega) omega_l            (s: brake slope, bb included)

Where the brake's slope s is negative (below omega_2 = 2.83 rad/s, report 4.1.1) the lower disc
is unstable.  Seen from the motor voltage to the motor angle, the plant's right-half-plane (RHP)
poles p are the lower disc's modes with the heavily damped motor attached, and its RHP zeros z
are the same modes with the motor held still (a zero of theta_u/u is a mode of the system
constrained to theta_u = 0).  Because the motor is so stiff (b_u = 2.42 N m s/rad against a
string of 0.0775 N m/rad), p and z almost coincide.  For a plant with an RHP pole p and RHP
zeros z_i, every linear time-invariant controller that stabilises it has (Skogestad and
Postlethwaite, Multivariable Feedback Control, 2nd ed., Theorem 5.3)::

    ||S||_inf, ||T||_inf  >=  prod_i |z_i + conj(p)| / |z_i - p|

and a loop with ||T||_inf = M is destabilised by a multiplicative input error of 1/M (a motor
constant 1/M off, a lag or delay with omega tau ~ 1/M at the crossover).  On the nominal rig the
bound is about 870 at 1 rad/s (0.12 % of model error in km destabilises), 92 at 2 rad/s (1.1 %),
23 at 2.5 rad/s (4.3 %) and 1 from omega_2 up (:func:`motor_angle_limit`,
``benchmarks/bench_motor_angle_limit.py``).  An observer-based controller is such a controller
about its operating point, so its low-speed performance needs the model to within that fraction;
with km +-5 % and lags of tens of ms it can only hold where the brake is (nearly) stable.  A
controller that also reads the lower encoder has no such zeros.
"""

from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from drillgym import RigParams
from drillgym.errors import InputError
from drillgym.friction import lower_friction_slope

__all__ = [
    "MotorAngleLimit",
    "brake_slope",
    "motor_angle_model",
    "motor_angle_limit",
    "motor_angle_limits",
    "tolerated_error",
]


def brake_slope(omega: float, params: RigParams) -> float:
    """Slope dTfl/domega of the brake law at lower speed ``omega`` > 0 (N m s/rad), bb included."""
    return float(lower_friction_slope(np.array([max(float(omega), 1e-6)]), params)[0])


def _state_matrices(params: RigParams, slopes: np.ndarray) -> np.ndarray:
    """The state matrices (k, 4, 4) of the linearised rig (states theta_u, omega_u, alpha, omega_l) at the brake
    slopes ``slopes`` (N m s/rad, (k,))."""
    p = params
    A = np.zeros((slopes.size, 4, 4))
    A[:, 0, 1] = 1.0
    A[:, 1, 1] = -(p.bu + p.dbu) / p.Ju
    A[:, 1, 2] = p.ktheta / p.Ju
    A[:, 2, 1] = -1.0
    A[:, 2, 3] = 1.0
    A[:, 3, 2] = -p.ktheta / p.Jl
    A[:, 3, 3] = -slopes / p.Jl
    return A


def motor_angle_model(params: RigParams, omega: float) -> control.StateSpace:
    """The torsional rig about the slip equilibrium at ``omega`` (rad/s): input u (V), output the
    motor angle theta_u (rad); states (theta_u, omega_u, alpha, omega_l)."""
    p = params
    A = _state_matrices(p, np.array([brake_slope(omega, p)]))[0]
    B = np.array([[0.0], [p.km / p.Ju], [0.0], [0.0]])
    C = np.array([[1.0, 0.0, 0.0, 0.0]])
    return control.ss(A, B, C, np.zeros((1, 1)))


def _constrained_modes(params: RigParams, slopes: np.ndarray) -> np.ndarray:
    """The zeros of theta_u/u (1/s, (k, 2)) at the brake slopes ``slopes`` (N m s/rad, (k,)): the modes of the rig
    with the motor held still, roots of Jl s^2 + slope s + k_theta (alpha' = omega_l, omega_u = 0)."""
    p = params
    A = np.zeros((slopes.size, 2, 2))
    A[:, 0, 1] = 1.0
    A[:, 1, 0] = -p.ktheta / p.Jl
    A[:, 1, 1] = -slopes / p.Jl
    return np.linalg.eigvals(A).astype(complex)


@dataclass(frozen=True)
class MotorAngleLimit:
    """The motor-angle loop at one operating point: RHP poles and zeros and the lower bound on the peak
    sensitivity and complementary sensitivity of every stabilising LTI controller.

    Parameters
    ----------
    omega : float
        Lower-disc speed of the equilibrium (rad/s).
    slope : float
        Brake slope dTfl/domega there (N m s/rad).
    rhp_poles, rhp_zeros : tuple of complex
        Right-half-plane poles and zeros of theta_u/u (1/s).
    bound : float
        Lower bound on ||S||_inf and ||T||_inf (1 without an RHP pole).
    """

    omega: float
    slope: float
    rhp_poles: tuple[complex, ...]
    rhp_zeros: tuple[complex, ...]
    bound: float

    @property
    def tolerated(self) -> float:
        """Largest relative input error (fraction) that the best loop can tolerate: 1/bound."""
        return tolerated_error(self.bound)


def tolerated_error(bound: float) -> float:
    """1/bound: the relative multiplicative error (e.g. in km) that destabilises a loop whose
    complementary sensitivity peaks at ``bound``."""
    return 1.0 / bound if bound > 0 else float("inf")


def motor_angle_limit(params: RigParams | None, omega: float) -> MotorAngleLimit:
    """RHP poles and zeros of theta_u/u at an equilibrium, and the bound they set on any controller.

    The bound is max_p prod_z |z + conj p| / |z - p| on ||S||_inf and ||T||_inf (1 when there is no RHP
    pole).

    Parameters
    ----------
    params : RigParams or None
        Base parameters; None: the identified set.
    omega : float
        Lower-disc speed of the equilibrium (rad/s), > 0.

    Returns
    -------
    MotorAngleLimit
        Poles, zeros and the bound; ``tolerated`` is the largest relative input error the best loop
        tolerates.
    """
    if not (np.isfinite(omega) and omega > 0):
        raise InputError(f"omega must be a positive speed (rad/s), got {omega!r}")
    return motor_angle_limits(params, [float(omega)])[0]


def motor_angle_limits(params: RigParams | None, omegas) -> list[MotorAngleLimit]:
    """:func:`motor_angle_limit` at several equilibria at once (one batched eigenvalue call for the poles,
    one for the zeros).

    Parameters
    ----------
    params : RigParams or None
        Base parameters; None: the identified set.
    omegas : sequence of float
        Lower-disc speeds of the equilibria (rad/s), each > 0.

    Returns
    -------
    list of MotorAngleLimit
        One per speed, in the order given.
    """
    p = params or RigParams()
    w = np.atleast_1d(np.asarray(omegas, dtype=float))
    if not np.all(np.isfinite(w) & (w > 0)):
        raise InputError(f"omega must be positive speeds (rad/s), got {omegas!r}")
    slopes = lower_friction_slope(np.maximum(w, 1e-6), p)
    poles = np.linalg.eigvals(_state_matrices(p, slopes))
    zeros = _constrained_modes(p, slopes)
    tol = 1e-9
    bounds = _bounds(poles, zeros, tol)
    rhp_p, rhp_z = poles.real > tol, zeros.real > tol
    return [
        MotorAngleLimit(float(w[k]), float(slopes[k]), tuple(poles[k, rhp_p[k]].tolist()),
                        tuple(zeros[k, rhp_z[k]].tolist()), float(bounds[k]))
        for k in range(w.size)
    ]  # fmt: skip


def _bounds(poles: np.ndarray, zeros: np.ndarray, tol: float) -> np.ndarray:
    """Per row k: max over the RHP poles p (real part > tol) of prod over the RHP zeros z of |z + conj p| / |z - p|
    (1 without an RHP pole); poles (K, np), zeros (K, nz)."""
    p, z = poles[:, :, None], zeros[:, None, :]
    ratio = np.abs(z + np.conj(p)) / np.maximum(np.abs(z - p), 1e-300)
    factors = np.where(zeros.real[:, None, :] > tol, ratio, 1.0)
    products = np.where(poles.real > tol, np.prod(factors, axis=2), 1.0)
    return np.maximum(products.max(axis=1, initial=1.0), 1.0)
