"""A camera on the arm: the world's camera (world/arm_camera.py, its own robot code) sees a
dense marker field; its corners (projected, 0.1 px noise) feed the estimator.

Bounds are 4 reported std (one std from the fit's covariance scaled by its residual)."""

from __future__ import annotations

import numpy as np
import pytest

import dataclasses

from vision_cal.camera.arm import LABELS, ArmView, T_sheet_flange, fit_arm_camera
from vision_cal.estimate.verdict import judge_camera_poses
from vision_cal.model.kinematics import ScaraParams
from vision_cal.world import arm_camera as world
from vision_cal.world.sheet import make_sheet
from vision_cal.world.truth_model import TrueRobot

N_STD = 4.0
SIZE = (800, 600)
K = np.array([[900.0, 0, 399.5], [0, 900.0, 299.5], [0, 0, 1]])
TRUTH = TrueRobot(344.05, 259.87, (-2.57, -8.13), (-424.26, -230.35))
NOMINAL = ScaraParams(350.0, 260.0, 0.0, 0.0, -410.0, -240.0)


def _field():
    """The marker field: 14 x 10 markers of 18 mm over an A2 sheet."""
    return make_sheet(size_mm=(594.0, 420.0), bottom_left_mm=(-297.0, -210.0),
                      dictionary="DICT_5X5_250", marker_mm=18.0, grid=(14, 10), margin_mm=12.0)


def _plan(n, rng, *, turn_j4=True, truth=TRUTH):
    """Commands whose flange lands over the sheet: both elbows, joint 4 turned."""
    out = []
    while len(out) < n:
        q = np.array([rng.uniform(-60, 60), rng.uniform(-150, 150)])
        xy = truth.pen_mm(q[None])[0]
        if abs(xy[0]) < 230 and abs(xy[1]) < 150 and abs(q[1]) > 20:
            out.append((q, rng.uniform(-170, 170) if turn_j4 else 0.0))
    return out


def _views(plan, X, rng, noise_px=0.1, repeatability_mm=0.01, truth=TRUTH):
    """Each photo: the flange off its place by the robot's repeatability (per axis), the
    corners by ``noise_px``."""
    corners = np.concatenate([m.corners_mm for m in _field().markers])
    q = np.array([p[0] for p in plan])
    j4 = np.array([p[1] for p in plan])
    T_sf = world.T_sheet_flange(truth, q, j4)
    T_sf[:, :2, 3] += rng.normal(0, repeatability_mm, (len(q), 2))
    views = []
    for i, T in enumerate(np.linalg.inv(T_sf @ X)):
        pc = np.column_stack([corners, np.zeros(len(corners))]) @ T[:3, :3].T + T[:3, 3]
        uv = pc[:, :2] / pc[:, 2:3] * K[0, 0] + K[:2, 2]
        inside = (uv[:, 0] > 5) & (uv[:, 0] < SIZE[0] - 6) & (uv[:, 1] > 5) & (uv[:, 1] < SIZE[1] - 6)
        inside = inside.reshape(-1, 4).all(axis=1).repeat(4)     # whole markers only
        views.append(ArmView(f"p{i}", q[i], j4[i], corners[inside],
                             uv[inside] + rng.normal(0, noise_px, (inside.sum(), 2))))
    return views


def _truth_vector(X):
    return np.array([TRUTH.L1_mm, TRUTH.L2_mm, *TRUTH.zero_deg, *TRUTH.base_mm])


@pytest.mark.parametrize("seed", [3])
def test_robot_and_T_flange_camera_found_within_their_std(seed):
    rng = np.random.default_rng(seed)
    X = world.T_flange_camera_true(rng)
    views = _views(_plan(24, rng), X, rng)
    assert min(len(v.corners_mm) for v in views) >= 16
    fit = fit_arm_camera(views, K, None, NOMINAL)
    sd = fit.std
    p = fit.params
    err = np.array([p.L1_mm, p.L2_mm, p.z1_deg, p.z2_deg, p.base_x_mm, p.base_y_mm]) - _truth_vector(X)
    assert np.all(np.abs(err) < N_STD * sd[:6]), dict(zip(LABELS, err / sd[:6]))
    dt = fit.T_flange_camera[:3, 3] - X[:3, 3]
    assert np.all(np.abs(dt) < N_STD * sd[9:12]), (dt, sd[9:12])
    R = fit.T_flange_camera[:3, :3] @ X[:3, :3].T
    dr = np.degrees(0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]))
    assert np.all(np.abs(dr) < N_STD * sd[6:9]), (dr, sd[6:9])
    assert fit.not_identifiable == []
    assert fit.rms_px < 0.2          # the 0.1 px noise, per axis, is all that is left


def relative_motion(params: ScaraParams, q_deg, j4_deg, T_flange_camera) -> np.ndarray:
    """(N-1, 4, 4) camera motion from photo 0 to each later photo (camera frames): what
    AX = XB hand-eye sees."""
    T = T_sheet_flange(params, q_deg, j4_deg) @ np.asarray(T_flange_camera, float)
    return np.array([np.linalg.inv(T[0]) @ Ti for Ti in T[1:]])


def test_planar_motion_leaves_the_height_to_the_sheet_plane():
    """Relative camera motions (classic AX = XB hand-eye) are the same for any camera
    height; the poses in the sheet frame are not, and the fit finds the height."""
    rng = np.random.default_rng(8)
    X = world.T_flange_camera_true(rng)
    plan = _plan(6, rng)
    q = np.array([p[0] for p in plan])
    j4 = np.array([p[1] for p in plan])
    params = ScaraParams(TRUTH.L1_mm, TRUTH.L2_mm, *TRUTH.zero_deg, *TRUTH.base_mm)
    X_up = X.copy()
    X_up[2, 3] += 30.0
    assert np.allclose(relative_motion(params, q, j4, X), relative_motion(params, q, j4, X_up),
                       atol=1e-9)
    S_a = world.T_sheet_flange(TRUTH, q, j4) @ X       # camera -> sheet, the world's
    S_b = world.T_sheet_flange(TRUTH, q, j4) @ X_up
    assert np.abs(S_a[:, 2, 3] - S_b[:, 2, 3]).min() > 29.9


def test_without_joint_4_turns_L2_and_the_camera_offset_are_not_identified():
    rng = np.random.default_rng(5)
    X = world.T_flange_camera_true(rng)
    views = _views(_plan(16, rng, turn_j4=False), X, rng)
    fit = fit_arm_camera(views, K, None, NOMINAL)
    assert "L2_mm" in fit.not_identifiable and "cam_x_mm" in fit.not_identifiable


def _verdict(fit, **kw):
    return judge_camera_poses(fit.flange_residual_mm, fit.flange_sigma_mm,
                              fit.flange_heldout_mm, n_params=fit.n_params_xy, **kw)


def test_clean_poses_sit_on_the_noise_floor():
    """Corner noise and the robot's repeatability are all there is: the residual over the
    floor is 1 within its spread (sqrt(chi2 / dof) on ~40 dof: std ~0.11, 4 std allowed)."""
    rng = np.random.default_rng(11)
    X = world.T_flange_camera_true(rng)
    fit = fit_arm_camera(_views(_plan(24, rng), X, rng), K, None, NOMINAL)
    v = _verdict(fit, repeatability_mm=0.01)
    assert 0.55 < v.residual_over_floor < 1.45, v.floor
    assert v.status in ("ready", "check") and not v.floor["beyond"], v.reasons
    assert v.expected_target_error_mm < 0.1


def test_an_unmodelled_gear_ratio_error_is_never_ready():
    """Joint 2 turns 1.0003 times its command (up to ~0.1 mm at the flange): the base
    model plus camera cannot take it, and the residual says so."""
    rng = np.random.default_rng(11)
    truth = dataclasses.replace(TRUTH, scale=(0.0, 3e-4))
    X = world.T_flange_camera_true(rng)
    fit = fit_arm_camera(_views(_plan(24, rng, truth=truth), X, rng, truth=truth), K, None,
                         NOMINAL)
    v = _verdict(fit, repeatability_mm=0.01)
    assert v.status != "ready" and v.floor["beyond"], v.floor
    assert any("noise floor" in r for r in v.reasons)


def test_poses_that_do_not_separate_a_parameter_are_not_reliable():
    rng = np.random.default_rng(5)
    X = world.T_flange_camera_true(rng)
    fit = fit_arm_camera(_views(_plan(16, rng, turn_j4=False), X, rng), K, None, NOMINAL)
    from vision_cal.actions.arm_camera import undetermined_reasons

    v = _verdict(fit, reasons=undetermined_reasons(fit, "flange"))
    assert v.status == "not reliable" and "L2_mm" in v.reasons[0], v.reasons
