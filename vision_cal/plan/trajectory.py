"""Joint trajectories for a plan: clamped cubic segments sampled at a fixed rate.

Conventions:

- Angles in degrees (``q_deg``), velocities in deg/s, accelerations in deg/s^2, time in s.
- Every waypoint (home, each overshoot via point, each mark) is a *stop*: the arm moves
  between consecutive waypoints along one cubic with zero velocity at both ends, the two
  joints sharing the segment's duration. Such a cubic is monotone, so a joint's last
  motion before a mark has the sign of (mark - previous waypoint) and never overshoots:
  this is what honours a plan's approach directions (the seed paper's trajectories are
  cubic splines too, sampled every 0.016 s).
- For a cubic with zero end velocities from a to b in T seconds the peak velocity is
  ``1.5 |b - a| / T`` and the peak acceleration ``6 |b - a| / T^2``; each segment's T is the
  smallest multiple of ``dt_s`` meeting both limits for both joints, so every knot falls
  on a sample and the samples are exactly ``dt_s`` apart.
- At each mark the arm dwells ``dwell_s`` (rounded up to a multiple of ``dt_s``) and the
  pen goes down at the end of the dwell. Via points have no dwell.
- A segment with no motion (a mark at the current pose) takes no time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from vision_cal.dataset.io import atomic_write_text
from vision_cal.errors import VisionCalError
from vision_cal.model.motion import ACCEL_DEG_S2, SPEED_DEG_S, TRAJECTORY_DT_S


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A sampled joint trajectory (all arrays read-only by convention).

    t_s (K,), q_deg (K, 2), qd_deg_s (K, 2), qdd_deg_s2 (K, 2): samples every ``dt_s``.
    waypoints_deg (M, 2) and knot_t_s (M,): each waypoint and the time it is reached.
    mark_index (M,): index of the mark a waypoint is (-1 for home and via points).
    pen_t_s (N,): pen-down time of each mark (end of its dwell); pen_down (K,) bool marks
    the sample at each of those times.
    """

    t_s: np.ndarray
    q_deg: np.ndarray
    qd_deg_s: np.ndarray
    qdd_deg_s2: np.ndarray
    knot_t_s: np.ndarray
    waypoints_deg: np.ndarray
    mark_index: np.ndarray
    pen_t_s: np.ndarray
    pen_down: np.ndarray
    dt_s: float
    spline: CubicHermiteSpline

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1])

    def evaluate(self, t_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reference at times ``t_s`` (K,) (a scalar is K = 1): (q_deg, qd_deg_s,
        qdd_deg_s2), each (K, 2).

        Before the start and after the end the arm rests at the first/last waypoint.
        """
        t_in = np.atleast_1d(np.asarray(t_s, dtype=float))
        t = np.clip(t_in, self.spline.x[0], self.spline.x[-1])
        q = self.spline(t)
        qd = self.spline(t, 1)
        qdd = self.spline(t, 2)
        outside = (t_in < self.spline.x[0]) | (t_in > self.spline.x[-1])
        qd[outside] = 0.0
        qdd[outside] = 0.0
        return q, qd, qdd


def plan_waypoints(marks, *, home_deg=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Waypoints (M, 2) deg of a plan and which mark each is (M,) (-1: home or a via point).

    Row 0 is home; then, for each mark in drawing order, its ``via_deg`` then the mark.
    """
    rows = [np.asarray(home_deg, dtype=float)]
    index = [-1]
    for i, m in enumerate(marks):
        for v in m.via_deg:
            rows.append(np.asarray(v, dtype=float))
            index.append(-1)
        rows.append(np.asarray(m.joints_deg, dtype=float))
        index.append(i)
    wp = np.vstack(rows).reshape(-1, 2)
    if not np.all(np.isfinite(wp)):
        raise VisionCalError("waypoints must be finite numbers", field="marks")
    return wp, np.asarray(index, dtype=int)


#: the most samples a trajectory may have: 10^6 at 16 ms is 4.4 hours of motion and a CSV of
#: about 60 MB; a million targets would need 10^8 samples and gigabytes of memory
MAX_TRAJECTORY_SAMPLES = 1_000_000


def _too_long(n_samples: int, dt_s: float, n_marks: int):
    raise VisionCalError(
        f"the trajectory through {n_marks} marks would have at least {n_samples:,} samples "
        f"({n_samples * dt_s / 3600:.1f} h at {dt_s * 1000:g} ms), more than "
        f"{MAX_TRAJECTORY_SAMPLES:,}: split the targets into several files",
        field="trajectory")


def check_length(n_marks: int, *, dt_s: float = TRAJECTORY_DT_S, dwell_s: float = 0.3) -> None:
    """Refuse, before anything is planned, a trajectory through ``n_marks`` marks that would
    exceed :data:`MAX_TRAJECTORY_SAMPLES` on its dwells alone."""
    n_dwell = int(np.ceil(dwell_s / dt_s - 1e-9)) if dwell_s > 0 else 0
    if n_marks * max(n_dwell, 1) + 1 > MAX_TRAJECTORY_SAMPLES:
        _too_long(n_marks * max(n_dwell, 1) + 1, dt_s, n_marks)


def segment_duration_s(delta_deg, *, vmax_deg_s, amax_deg_s2, dt_s: float) -> float:
    """Shortest duration (a multiple of ``dt_s``) of a zero-end-velocity cubic moving
    ``delta_deg`` (2,) within the velocity and acceleration limits."""
    d = np.abs(np.asarray(delta_deg, dtype=float))
    if not np.any(d > 0):
        return 0.0
    t = max(np.max(1.5 * d / np.asarray(vmax_deg_s, dtype=float)),
            np.max(np.sqrt(6.0 * d / np.asarray(amax_deg_s2, dtype=float))))
    n = int(np.ceil(t / dt_s - 1e-9))
    return max(n, 1) * dt_s


def joint_trajectory(waypoints_deg, *, dt_s: float = TRAJECTORY_DT_S, vmax_deg_s=SPEED_DEG_S,
                     amax_deg_s2=ACCEL_DEG_S2, dwell_s: float = 0.3,
                     mark_index=None) -> Trajectory:
    """Sampled trajectory through ``waypoints_deg`` (M, 2), stopping at each waypoint.

    ``mark_index`` (M,) says which waypoints are marks (>= 0) and which are home/via
    points (-1); by default row 0 is the start and every other row is a mark.
    """
    wp = np.asarray(waypoints_deg, dtype=float)
    if wp.ndim != 2 or wp.shape[1] != 2 or len(wp) < 1:
        raise VisionCalError(f"waypoints must have shape (M, 2), got {wp.shape}",
                             field="waypoints_deg")
    if not np.all(np.isfinite(wp)):
        raise VisionCalError("waypoints must be finite numbers", field="waypoints_deg")
    if not dt_s > 0:
        raise VisionCalError(f"dt_s must be positive, got {dt_s}", field="dt_s")
    vmax = np.broadcast_to(np.asarray(vmax_deg_s, dtype=float), (2,))
    amax = np.broadcast_to(np.asarray(amax_deg_s2, dtype=float), (2,))
    if np.any(vmax <= 0) or np.any(amax <= 0):
        raise VisionCalError("velocity and acceleration limits must be positive")
    if mark_index is None:
        mark_index = np.concatenate([[-1], np.arange(len(wp) - 1)])
    mark_index = np.asarray(mark_index, dtype=int)
    if mark_index.shape != (len(wp),):
        raise VisionCalError(f"mark_index must have shape ({len(wp)},)", field="mark_index")

    n_dwell = int(np.ceil(dwell_s / dt_s - 1e-9)) if dwell_s > 0 else 0
    n_marks = int(np.count_nonzero(mark_index >= 0))
    check_length(n_marks, dt_s=dt_s, dwell_s=dwell_s)  # before any per-mark work
    # integer sample counts keep every knot exactly on the sampling grid
    k_now = 0
    knot_k = np.zeros(len(wp), dtype=np.int64)
    spl_k = [0]
    spl_q = [wp[0]]
    pen_k = []
    if mark_index[0] >= 0:
        pen_k.append(k_now + n_dwell)
    for j in range(1, len(wp)):
        T = segment_duration_s(wp[j] - wp[j - 1], vmax_deg_s=vmax, amax_deg_s2=amax, dt_s=dt_s)
        n = int(round(T / dt_s))
        if n > 0:
            k_now += n
            spl_k.append(k_now)
            spl_q.append(wp[j])
        knot_k[j] = k_now
        if mark_index[j] >= 0:
            if n_dwell:
                k_now += n_dwell
                spl_k.append(k_now)
                spl_q.append(wp[j])
            pen_k.append(k_now)
    if len(spl_k) == 1:  # nothing moves and nothing dwells: a single sample
        spl_k.append(1)
        spl_q.append(wp[0])
        k_now = max(k_now, 1)
    if k_now + 1 > MAX_TRAJECTORY_SAMPLES:
        _too_long(k_now + 1, dt_s, n_marks)
    x = np.asarray(spl_k, dtype=float) * dt_s
    spline = CubicHermiteSpline(x, np.vstack(spl_q), np.zeros((len(x), 2)), axis=0)
    t = np.arange(k_now + 1) * dt_s
    q = spline(t)
    qd = spline(t, 1)
    qdd = spline(t, 2)
    pen_down = np.zeros(len(t), dtype=bool)
    pen_down[np.asarray(pen_k, dtype=int)] = True
    return Trajectory(t_s=t, q_deg=q, qd_deg_s=qd, qdd_deg_s2=qdd, knot_t_s=knot_k * dt_s,
                      waypoints_deg=wp.copy(), mark_index=mark_index.copy(),
                      pen_t_s=np.asarray(pen_k, dtype=float) * dt_s, pen_down=pen_down,
                      dt_s=float(dt_s), spline=spline)


def plan_trajectory(marks, *, home_deg=(0.0, 0.0), **kwargs) -> Trajectory:
    """:func:`joint_trajectory` through :func:`plan_waypoints` of ``marks``."""
    wp, idx = plan_waypoints(marks, home_deg=home_deg)
    return joint_trajectory(wp, mark_index=idx, **kwargs)


def write_trajectory_csv(path, traj: Trajectory):
    """Write ``t_s,q1_deg,q2_deg,qd1_deg_s,qd2_deg_s,pen`` (pen 1 at pen-down samples)."""
    lines = ["t_s,q1_deg,q2_deg,qd1_deg_s,qd2_deg_s,pen"]
    for t, q, qd, p in zip(traj.t_s, traj.q_deg, traj.qd_deg_s, traj.pen_down):
        lines.append(f"{t:.3f},{q[0]:.6f},{q[1]:.6f},{qd[0]:.6f},{qd[1]:.6f},{int(p)}")
    return atomic_write_text(path, "\n".join(lines) + "\n")
