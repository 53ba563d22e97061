import math

import numpy as np

from vision_cal.model.rms import rms, rms_2d


def test_rms_2d_is_the_length_not_per_coordinate():
    # |(3, 4)| = 5 and |(0, 0)| = 0: sqrt((25 + 0) / 2); per coordinate would be sqrt(25 / 4)
    assert rms_2d([[3.0, 4.0], [0.0, 0.0]]) == math.sqrt(12.5)
    assert rms([3.0, -4.0]) == math.sqrt(12.5)
    assert math.isnan(rms_2d(np.zeros((0, 2)))) and math.isnan(rms([]))
