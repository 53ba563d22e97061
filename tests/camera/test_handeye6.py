"""The hand-eye of any arm from photos of a board and the robot's poses (issue 40): the
closed form, the one least squares and its stds, and every refusal, on the six-axis world's
projected corners (worlds/six_axis.py, its own arm and lens; no photos rendered here)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.camera.handeye_helpers import pose_offset
from vision_cal.camera.handeye import estimated_lens_fit, fit_handeye
from vision_cal.camera.handeye_closed import inv_T, solve_axzb
from vision_cal.camera.handeye_lsq import Problem, View, lens_vector
from vision_cal.camera.handeye_stats import (_kinematic_low_rank, _low_rank, kinematic_kernel,
                                             noise_components, sandwich)
from vision_cal.camera.handeye_verdict import judge_handeye, lens_check
from vision_cal.config import DEFAULT
from vision_cal.errors import CalibrationError, VisionCalError
from worlds.six_axis import Lens, make_world, observe, shots

#: a small lens: the corners' pixels are what matter here, not their count
LENS = Lens(np.array([[900.0, 0.0, 322.0], [0.0, 900.0, 238.0], [0.0, 0.0, 1.0]]),
            np.array([-0.12, 0.08, 4e-4, -3e-4, 0.0]), (640, 480))


def _views(seed: int, mount: str, n: int = 10, **kw):
    w = make_world(seed, mount=mount, lens=LENS, **kw)
    rng = np.random.default_rng(seed + 1)
    sh = shots(w, n, seed)
    return w, [View(s.name, s.T_robot_flange, *observe(w, s, rng)) for s in sh]


#: one distortion model (the world's lens has them all): the model choice is the real
#: photos' test; here each fit is made once
ONE_MODEL = replace(DEFAULT.handeye_photos, lens_models="k1 k2 p1 p2")


def _fit(views, w, mount, **kw):
    return fit_handeye(views, mount, w.lens.size_px, config=ONE_MODEL, **kw)


@pytest.mark.parametrize("mount", ["fixed", "arm"])
def test_closed_form_is_exact_on_exact_poses(mount):
    """Noise-free board poses and reported poses: AX = ZB gives both transforms to
    1e-6 mm (no start, no OpenCV hand-eye call)."""
    w, _ = _views(3, mount, n=5, joint_noise_deg=0.0)
    sh = shots(w, 5, 3)
    A = [s.T_robot_flange if mount == "fixed" else inv_T(s.T_robot_flange) for s in sh]
    B = [s.T_camera_board for s in sh]
    sol = solve_axzb(A, B)
    assert np.abs(sol.X - w.Y).max() < 1e-6 and np.abs(sol.Z - w.X).max() < 1e-6
    assert abs(solve_axzb(A, B, free_scale=True).scale - 1.0) < 1e-9
    A_m = np.array(A)
    A_m[:, :3, 3] /= 1000.0                  # the robot's translations in metres
    assert abs(solve_axzb(A_m, B, free_scale=True).scale - 1000.0) < 1e-6


def test_jacobian_is_the_derivative():
    """The least squares' analytic Jacobian (shared unknowns and each photo's pose error)
    against central differences."""
    w, views = _views(4, "arm", n=3)
    pr = Problem(views, "arm", w.X, w.Y, lens_vector(w.lens.K, w.lens.dist), np.ones(9, bool))
    p = pr.start()
    Js, Jd = pr.jacobians(p)
    for k, h in ((0, 1e-4), (4, 1e-3), (8, 1e-4), (11, 1e-3), (12, 1e-2), (16, 1e-7)):
        d = np.zeros_like(p)
        d[k] = h
        num = (pr.predict(p + d) - pr.predict(p - d)).ravel() / (2 * h)
        assert np.allclose(Js[:, k], num, rtol=1e-5, atol=1e-6 * np.abs(num).max())
    pd = Problem(views, "arm", w.X, w.Y, pr.lens0, pr.free, pose_sigma=(1.0, 1.0))
    q = pd.start()
    for k, h in ((0, 1e-4), (5, 1e-3)):
        d = np.zeros_like(q)
        d[pd.n_shared + k::6] = h
        num = (pd.predict(q + d) - pd.predict(q - d)).ravel() / (2 * h)
        assert np.allclose(Jd[:, k], num, rtol=1e-5, atol=1e-6 * np.abs(num).max())


@pytest.mark.parametrize("mount,seed", [("fixed", 21), ("arm", 22)])
def test_recovers_both_transforms_within_their_std(mount, seed):
    """A lens the estimator is not told, a controller's pose noise: every pose parameter
    within 3.5 std of the truth, the held-out photos within what is stated, ready."""
    w, views = _views(seed, mount, n=10, joint_noise_deg=0.02)
    f = _fit(views, w, mount)
    err = np.r_[pose_offset(w.X, f.X), pose_offset(w.Y, f.Y)]
    assert np.all(np.abs(err / f.std[:12]) < 3.5), err / f.std[:12]
    obs, stated, _, _ = f.heldout_rms()
    assert obs < 2.0 * stated and f.left_out == {}
    assert judge_handeye(f).status == "ready"


@pytest.mark.parametrize("seed", [23, 32])
def test_declared_lens_ten_percent_off_is_never_ready(seed):
    """The focal length declared 10 % long: refused (the board's motion no longer matches
    the robot's: seed 23) or named against a lens estimated from the same photos (seed
    32), never ready."""
    w, views = _views(seed, "fixed", n=10, joint_noise_deg=0.02)
    K = w.lens.K.copy()
    K[0, 0] *= 1.1
    K[1, 1] *= 1.1
    try:
        f = _fit(views, w, "fixed", lens=(K, w.lens.dist))
    except CalibrationError as e:
        assert "focal length" in str(e)
        return
    free = estimated_lens_fit(views, f, config=ONE_MODEL)
    v = judge_handeye(f, lens_check=lens_check(f, free))
    assert v.status != "ready" and "the declared lens disagrees" in " ".join(v.reasons)


def test_swapped_units_are_named():
    """Poses in metres read as millimetres: the robot moved 1/1000 of the board."""
    w, views = _views(24, "fixed", n=6)
    bad = [View(v.name, np.diag([1, 1, 1, 1.0]) @ _scaled(v.T_robot_flange, 1e-3), v.ids,
                v.board_mm, v.px) for v in views]
    with pytest.raises(VisionCalError, match="in metres, read as millimetres"):
        _fit(bad, w, "fixed", lens=(w.lens.K, w.lens.dist), units="mm")
    inch = [View(v.name, _scaled(v.T_robot_flange, 1 / 25.4), v.ids, v.board_mm, v.px)
            for v in views]
    with pytest.raises(VisionCalError, match="inches"):
        _fit(inch, w, "fixed", lens=(w.lens.K, w.lens.dist), units="mm")


def _scaled(T, s):
    T = T.copy()
    T[:3, 3] *= s
    return T


def test_poses_off_by_one_photo_are_named():
    """Each photo paired with the next photo's pose: refused, naming the shift."""
    w, views = _views(25, "fixed", n=8)
    shifted = [View(v.name, views[i + 1].T_robot_flange, v.ids, v.board_mm, v.px)
               for i, v in enumerate(views[:-1])]
    with pytest.raises(VisionCalError, match="shifted by one photo"):
        _fit(shifted, w, "fixed", lens=(w.lens.K, w.lens.dist))


@pytest.mark.parametrize("reading", ["inverse", "mount"])
def test_conventions_are_named(reading):
    """Poses given as T_flange_robot, or a camera on the arm declared fixed: refused,
    naming the reading under which the rotations agree."""
    w, views = _views(26, "fixed", n=6)
    if reading == "inverse":
        bad = [View(v.name, inv_T(v.T_robot_flange), v.ids, v.board_mm, v.px) for v in views]
        alts = {"T_flange_robot (the poses inverted)": [v.T_robot_flange for v in views]}
        with pytest.raises(VisionCalError, match="T_flange_robot"):
            _fit(bad, w, "fixed", lens=(w.lens.K, w.lens.dist), alternatives=alts)
    else:
        with pytest.raises(VisionCalError, match="--mount fixed"):
            _fit(views, w, "arm", lens=(w.lens.K, w.lens.dist))


def test_a_photo_of_another_board_is_left_out_and_named():
    """One photo shows a board of the same markers but other squares (its poses fit no
    camera): left out with its reason, the rest calibrated, not ready."""
    w, views = _views(27, "fixed", n=10, joint_noise_deg=0.02)
    other = make_world(27, mount="fixed", lens=LENS, joint_noise_deg=0.02,
                       board={"square_mm": 30.0, "marker_mm": 15.0})
    rng = np.random.default_rng(5)
    s = shots(other, 5, 27)[4]
    ids, _, px = observe(other, s, rng)
    views[4] = View(views[4].name, views[4].T_robot_flange, ids, views[4].board_mm, px)
    f = _fit(views, w, "fixed", lens=(w.lens.K, w.lens.dist))
    assert views[4].name in f.left_out and len(f.left_out) == 1
    v = judge_handeye(f)
    assert v.status != "ready" and views[4].name in " ".join(v.reasons)


def test_a_scara_is_sent_to_its_own_path():
    """Every flange turn about one axis (a SCARA's): refused, naming the unseen height
    and the 4-DOF path."""
    w, views = _views(28, "fixed", n=6)
    scara = []
    for i, v in enumerate(views):
        T = np.eye(4)
        a = np.radians(30.0 * i)
        T[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
        T[:3, 3] = [300.0 + 20 * i, 10.0 * i, 100.0]
        scara.append(View(v.name, T, v.ids, v.board_mm, v.px))
    with pytest.raises(CalibrationError, match="--z-mm"):
        _fit(scara, w, "fixed", lens=(w.lens.K, w.lens.dist))


def test_too_few_photos():
    w, views = _views(29, "fixed", n=3)
    with pytest.raises(CalibrationError, match="at least"):
        _fit(views, w, "fixed")


@pytest.mark.parametrize("mount", ["fixed", "arm"])
def test_a_kinematic_error_shared_by_nearby_poses_is_in_the_stds(mount):
    """Photos taken in nearby configurations (each joint within about 6 deg) share most of the
    robot's kinematic error, which the unknowns absorb unseen. Residuals drawn from the
    noise model (the detector's, a per-photo pose error, and a kinematic error of 0.3 mm
    shared by the kernel over the joints): the noise estimated from each residual states
    the unknowns' covariance that the draws show (each variance within 0.5x..2x of what
    the draws give; the robot's error taken as independent states 2-7x too little)."""
    w = make_world(7, mount=mount, lens=LENS)
    rng = np.random.default_rng(3)
    s0 = shots(w, 1, 7)[0]
    views = []
    for i in range(10):
        q = s0.q_deg + (rng.normal(0.0, 6.0, 6) if i else 0.0)
        s = replace(s0, name=str(i), q_deg=q, q_true_deg=q,
                    T_robot_flange=w.nominal.flange(q), T_camera_board=w.T_camera_board(q))
        views.append(View(s.name, s.T_robot_flange, *observe(w, s, rng), joints_deg=q))
    pr = Problem(views, mount, w.X, w.Y, lens_vector(LENS.K, LENS.dist), np.zeros(9, bool))
    Js, Jd = pr.jacobians(pr.start())
    kin = kinematic_kernel(views, 1.0)
    blocks = [np.flatnonzero(np.repeat(pr.view_of, 2) == i) for i in range(len(views))]
    U = [_low_rank(Jd, blocks, [0, 1, 2]), _low_rank(Jd, blocks, [3, 4, 5]),
         _kinematic_low_rank(Jd, blocks, kin)]
    sd = (0.15, 0.01, 0.05, 0.3)        # px, deg, mm per photo, mm kinematic
    Hi = np.linalg.pinv(Js.T @ Js)
    theta, stated = [], []
    for _ in range(60):
        e = sd[0] * rng.standard_normal(len(Js)) + sum(
            s * (u @ rng.standard_normal(u.shape[1])) for s, u in zip(sd[1:], U))
        theta.append(Hi @ Js.T @ e)
        noise = noise_components((e - Js @ theta[-1]).reshape(-1, 2), Js, Jd, pr.view_of, kin)
        stated.append(np.diag(sandwich(Js, Jd, pr.view_of, noise, kin)))
    ratio = np.var(np.array(theta), axis=0) / np.mean(stated, axis=0)
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio.round(2)
