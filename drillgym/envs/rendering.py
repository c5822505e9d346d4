"""Rendering of one rig: the two discs seen from above and a strip chart of omega_u, omega_l.

Matplotlib is imported only when a renderer is created (never on the step path).
'rgb_array' draws on an Agg canvas and returns an (H, W, 3) uint8 array; 'human'
shows the same figure in a window (interactive backend) and refreshes it per step.  Without a
display matplotlib falls back to a backend that cannot open a window: 'human' then warns once
(per renderer) that nothing is shown instead of doing nothing silently.
"""

from __future__ import annotations

import warnings
from collections import deque

import numpy as np

from ..errors import InputError

__all__ = ["RigRenderer"]

LATERAL_ZOOM = 10.0  # lateral displacement drawn 10x (a few mm on a 0.1 m disc)
#: matplotlib backends that draw to files or buffers only (no window)
NON_INTERACTIVE_BACKENDS = ("agg", "cairo", "pdf", "pgf", "ps", "svg", "template")


def can_show_windows(backend: str) -> bool:
    """Whether a matplotlib backend opens windows (False for 'agg', the fallback without a display)."""
    return backend.lower() not in NON_INTERACTIVE_BACKENDS


class RigRenderer:
    """Draws a rig state; ``record`` keeps the last ``history`` seconds for the strip chart."""

    def __init__(
        self, mode: str, history: float, control_dt: float, lateral: bool, size: tuple = (6.4, 3.2), dpi: int = 80
    ) -> None:
        if mode not in ("human", "rgb_array"):
            raise InputError(f"render_mode must be 'human' or 'rgb_array', got {mode!r}")
        self.mode, self.lateral = mode, lateral
        n = max(2, int(round(history / control_dt)))
        self.t, self.wu, self.wl = deque(maxlen=n), deque(maxlen=n), deque(maxlen=n)
        self._size, self._dpi = size, dpi
        self._fig = None

    def clear(self) -> None:
        self.t.clear()
        self.wu.clear()
        self.wl.clear()

    def record(self, t: float, omega_u: float, omega_l: float) -> None:
        self.t.append(t)
        self.wu.append(omega_u)
        self.wl.append(omega_l)

    def _figure(self):
        if self._fig is None:
            if self.mode == "human":
                import matplotlib.pyplot as plt

                backend = plt.get_backend()
                if not can_show_windows(backend):
                    warnings.warn(
                        f"render_mode='human' but matplotlib's backend {backend!r} cannot open a window "
                        f"(no display?): nothing is shown; use render_mode='rgb_array' (frames as arrays, "
                        f"e.g. for gymnasium.wrappers.RecordVideo) or a display",
                        UserWarning,
                        stacklevel=2,
                    )
                plt.ion()
                self._fig = plt.figure(figsize=self._size, dpi=self._dpi)
            else:
                from matplotlib.backends.backend_agg import FigureCanvasAgg
                from matplotlib.figure import Figure

                self._fig = Figure(figsize=self._size, dpi=self._dpi)
                FigureCanvasAgg(self._fig)
        return self._fig

    def draw(self, theta_u: float, theta_l: float, X: float, Y: float, omega_ref: float, stuck: bool):
        """Draw the state; returns the RGB array in 'rgb_array' mode, None in 'human' mode."""
        fig = self._figure()
        fig.clf()
        ax_top = fig.add_axes((0.02, 0.1, 0.4, 0.8))
        ax_chart = fig.add_axes((0.52, 0.18, 0.45, 0.72))
        self._draw_discs(ax_top, theta_u, theta_l, X, Y, stuck)
        ax_chart.plot(self.t, self.wu, label="ω_u", lw=1.2)
        ax_chart.plot(self.t, self.wl, label="ω_l", lw=1.2)
        ax_chart.axhline(omega_ref, color="k", ls="--", lw=0.8, label="ω_ref")
        ax_chart.set_xlabel("t (s)")
        ax_chart.set_ylabel("rad/s")
        ax_chart.legend(loc="upper left", fontsize=7)
        fig.canvas.draw()
        if self.mode == "human":
            fig.canvas.flush_events()
            return None
        return np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()

    def _draw_discs(self, ax, theta_u, theta_l, X, Y, stuck) -> None:
        from matplotlib.patches import Circle

        ax.set_aspect("equal")
        ax.set_xlim(-1.6, 1.6)
        ax.set_ylim(-1.6, 1.6)
        ax.axis("off")
        # upper disc (radius 1.4, fixed centre), lower disc (radius 1, centre displaced, zoomed)
        ax.add_patch(Circle((0, 0), 1.4, fc="0.9", ec="0.4"))
        ax.plot([0, 1.4 * np.cos(theta_u)], [0, 1.4 * np.sin(theta_u)], color="tab:blue", lw=2)
        cx, cy = (LATERAL_ZOOM * X / 0.1, LATERAL_ZOOM * Y / 0.1) if self.lateral else (0.0, 0.0)
        ax.add_patch(Circle((cx, cy), 1.0, fc="tab:red" if stuck else "tab:orange", ec="k", alpha=0.6))
        ax.plot([cx, cx + np.cos(theta_l)], [cy, cy + np.sin(theta_l)], color="k", lw=2)
        ax.add_patch(Circle((cx + 0.7 * np.cos(theta_l), cy + 0.7 * np.sin(theta_l)), 0.12, fc="k"))
        ax.set_title("stuck" if stuck else "slipping", fontsize=8)

    def close(self) -> None:
        if self._fig is not None and self.mode == "human":
            import matplotlib.pyplot as plt

            plt.close(self._fig)
        self._fig = None
