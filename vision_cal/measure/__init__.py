"""Measuring the sheet: ArUco grid to sheet millimetres, pen marks to sub-pixel centres.

Frames and units: sheet frame S (x right, y up, mm) as in the dataset format; image pixels
(u, v) = (column, row), integer at pixel centres (OpenCV). Covariances in mm^2.

One photo is :func:`vision_cal.measure.detect.detect_image` then
:func:`vision_cal.measure.finish.finish_image`; a whole folder, photos to
marks (which dot is which mark is identify/'s), is
:func:`vision_cal.actions.measure_folder.measure_folder`.

Modules, by stage: ``listing`` (the photos to measure, checked), ``detect`` (stage 1:
markers and dot candidates, cached, in parallel), ``finish`` (stage 2: the lens, the
mapping, dots on the sheet), ``print_stage`` (the sheet as printed); below them ``aruco``
(markers, sub-pixel edges), ``mapping`` (lens + homography, lens estimate), ``dots`` (ink
dots and their centres on the sheet), ``types`` (the measurement's types and their JSON),
``cache`` (per-photo cache).
"""
