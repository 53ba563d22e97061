"""Shared render fixtures: one pyrender Photographer per test session, a small sheet."""

import numpy as np
import pytest

SIZE_PX = (640, 480)
F_PX = 800.0
PX_PER_MM = 8.0


@pytest.fixture(scope="session")
def K():
    from vision_cal.world.camera import camera_matrix

    return camera_matrix(size_px=SIZE_PX, f_px=F_PX)


@pytest.fixture(scope="session")
def photographer(K):
    from vision_cal.world.photo import Photographer

    ph = Photographer(size_px=SIZE_PX, K=K)
    yield ph
    ph.close()


@pytest.fixture(scope="session")
def small_sheet():
    """A 200 x 150 mm sheet with 3 x 2 markers: at 640 x 480 about 0.38 mm per pixel."""
    from vision_cal.world.sheet import make_sheet

    return make_sheet(size_mm=(200.0, 150.0), bottom_left_mm=(-100.0, -60.0), marker_mm=20.0,
                      grid=(3, 2), margin_mm=10.0)


@pytest.fixture(scope="session")
def small_marks(small_sheet):
    """Mark positions (N, 2) mm on a lattice, away from the markers' quiet zones."""
    xy = np.array([[x, y] for x in np.arange(-80.0, 81.0, 12.3) for y in np.arange(-30.0, 71.0, 11.7)])
    centres = np.stack([m.corners_mm.mean(axis=0) for m in small_sheet.markers])
    far = np.min(np.linalg.norm(xy[:, None] - centres[None], axis=2), axis=1) > 20.0
    return xy[far]
