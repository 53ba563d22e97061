"""The estimator's knobs in one place (OpenSfM-style configuration), recorded in
calibration.json (field ``config``) so that a result says how it was obtained.

Every threshold the measurement and the selection use is a field below, with its unit and
why it has its value. No module copies a field at import: each function reads the config it
is given when it is called (``config=None`` meaning :data:`DEFAULT`), so a config passed to
:func:`vision_cal.actions.pipeline.calibrate_dataset` (an :class:`EstimatorConfig`) changes every
stage, and all of it is written to calibration.json ``config`` (the report shows the
recorded values, not today's defaults). The parts, by key:

- ``markers``: photos and printed markers (:mod:`vision_cal.measure.aruco`,
  :mod:`vision_cal.measure.detect`);
- ``dots``: pen-mark detection and centring (:mod:`vision_cal.measure.dots`);
- ``association``: grouping and matching (:mod:`vision_cal.identify.associate`,
  :mod:`vision_cal.identify.infer`);
- ``selection``: the F-test level, cross-validation and outlier rule
  (:mod:`vision_cal.estimate.select`, :mod:`vision_cal.model.lsq`);
- ``fit``: identifiability of a least-squares fit (:mod:`vision_cal.model.lsq`);
- ``per_photo_offsets``: photos whose marks moved together (:mod:`vision_cal.estimate.photos`);
- ``sheet_fit``: the marker-corner gate of a photo (:mod:`vision_cal.measure.sheetfit`);
- ``grid``: the printed grid read around each dot (:mod:`vision_cal.measure.grid`);
- ``sheet_height``: the paper's height from parallax (:mod:`vision_cal.measure.height`);
- ``plan_match``: photos that do not belong to the session (:mod:`vision_cal.identify.plan_match`);
- ``photo_agreement``: a photo moved as a whole (:mod:`vision_cal.measure.photo_agreement`);
- ``grid_declaration``: a printed grid not where declared
  (:mod:`vision_cal.measure.grid_declaration`);
- ``smooth_residual``: a spatially smooth residual (:mod:`vision_cal.estimate.sheet`);
- ``discovery``: the scans for effects no candidate names (:mod:`vision_cal.estimate.discover`);
- ``joint4``: the joint-4 (tool offset) stage (:mod:`vision_cal.estimate.joint4`);
- ``handeye``: the hand-eye from pose pairs (:mod:`vision_cal.camera.pose_pairs`);
- ``handeye_photos``: the hand-eye from photos and the robot's poses, any arm
  (:mod:`vision_cal.camera.handeye`);
- ``verdict``: the noise-floor gate and the status rule (:mod:`vision_cal.estimate.verdict`,
  which judges a calibration.json with the config that file recorded);
- ``verify``: the check of a calibration on a new sheet, what moved and what still holds
  (:mod:`vision_cal.estimate.verify`, with the config the calibration recorded);
- ``uncertainty``: what a stated std holds beyond the fit's covariance (repeatability from
  repeated marks, the print not measured, the paper's scale, the halves' replication).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields


#: the calibration methods (``vision-cal --method``, :func:`vision_cal.actions.pipeline.calibrate_dataset`):
#: least squares with the effect diagnosis, and the seed paper's three-point circles
METHODS = ("lsq", "paper")


@dataclass(frozen=True)
class MarkerConfig:
    """Photos and the sheet's printed markers (``vision_cal.measure.aruco``,
    ``vision_cal.measure.detect``)."""

    min_markers: int = 4              # markers a photo must show: 4 give 16 corners, twice the
                                      # 8 a homography needs, so one bad marker is seen
    min_hull_fraction: float = 0.04   # the markers' convex hull / image area below this: the
                                      # sheet is too small in the photo to map it well
    blank_photo_std: float = 2.0      # grey levels: a photo whose std (every 4th pixel) is
                                      # below has no contrast (lens cap, dark frame), skipped


@dataclass(frozen=True)
class DotConfig:
    """Pen-mark detection and centring (``vision_cal.measure.dots``)."""

    ink_darkening: float = 0.30       # ink lowers the brightest channel by at least this fraction
    min_area_ratio: float = 0.25      # blob area / expected dot area below: noise, paper texture
    max_area_ratio: float = 1.9       # above: merged marks or a smudge
    huge_area_ratio: float = 6.0      # above: not a pen mark at all (arm, shadow, print)
    max_aspect: float = 1.5           # sheet-frame aspect ratio of a single dot
    min_solidity: float = 0.75        # blob area / convex hull area
    marker_margin_mm: float = 3.0     # masked around each printed marker (patch half-size + margin)
    fine_step_mm: float = 0.05        # sampling step of the resampled dot patch
    default_diameter_mm: float = 1.2  # pen mark diameter when session.json's pen block is absent
    model_floor_px: float = 0.02      # centroid error the print and sampling leave (px), added to
                                      # every dot's covariance (0.01-0.03 px seen on renders)
    unreliable_bg_residual: float = 2.5  # the sheet's own print rendered around the dot leaves
                                      # this many times the noise: ink it could not separate,
                                      # the mark is "unreliable" (marks over print: up to 1.45)
    unreliable_bg_residual_separable: float = 3.5  # the same for paper + grid lines alone
                                      # (clean renders: 0.7-1.1, and 3.2 by two bold lines
                                      # crossing, which the separable model cannot follow)
    unreliable_ink_shift_mm: float = 0.01  # over the sheet's own print: the centre moves more
                                      # than this when the pen's ink level is taken anywhere in
                                      # the spread of the dot's core, or the print's blur one
                                      # step sharper or softer while the photo cannot tell it
                                      # (a third of the 0.03 mm a mark must meet): it depends
                                      # on the model, the mark is "unreliable". Paper and
                                      # grid lines alone: ink the model leaves unexplained
                                      # beside the window would move the centre more than
                                      # this (clean marks: <= 7 um; a letter or number
                                      # touching the window: 14 um and more)
    unreliable_noise_sigmas: float = 3.5  # ... and more than this many times the std the
                                      # photo's noise gives that pull (a 2-D pull of noise alone
                                      # exceeds 3.5 std in 0.2 % of marks; clean marks on
                                      # renders: up to 2.7 std, at 0.26 mm/px up to 10 um)
    printed_edge_mm: float = 0.05     # over the sheet's own print: how far its edges may be
                                      # from where the layout puts them (half a pixel of the
                                      # 254 dpi raster another rasteriser draws; toner spreads
                                      # 0.03-0.06 mm): a centre moving more than
                                      # unreliable_ink_shift_mm with them is "unreliable"
    printed_edge_chi2: float = 4.0    # ... as far as the photo allows: the ground around the
                                      # mark fitted with the print's edges moved leaves this
                                      # many noise variances (2 std) more than with them where
                                      # the layout puts them (dots._edge_shift)
    ground_min_dots: int = 8          # dots on plain ground (paper and grid lines) a series
                                      # needs before its own ground level (a low quantile
                                      # of their background residuals) replaces the blank
                                      # paper's noise in the tests above (JPEG, low
                                      # resolution: issue 28)
    ground_quantile: float = 0.25     # that quantile: ink under up to 3/4 of the dots (a
                                      # sheet nobody describes) does not raise it
    views_per_dot: int = 5            # a dot is refined in its first this many photos (capture
                                      # order) where it was measured reliably; later photos keep
                                      # it only as seen (grouping, which marks a photo shows, a
                                      # photo moved as a whole): the finish stage linear in
                                      # photos and marks, not their product. Past a few views a
                                      # mark's std hardly falls (association.common_fraction
                                      # of each view's error is common to them all: 5 views
                                      # give 0.60 of one view's variance, 38 give 0.51). 0:
                                      # every photo (issue 33)


@dataclass(frozen=True)
class AssociationConfig:
    """Grouping dots across photos and matching them to planned marks
    (``vision_cal.identify.associate``)."""

    group_tol_diameters: float = 0.4  # dots of two photos closer than this many mark diameters
    group_tol_min_mm: float = 0.3     # ... (at least this many mm) are the same mark
    common_fraction: float = 0.5      # share of a dot's covariance common to all its photos
                                      # (the sheet mapping's error), not averaged away
    max_zero_deg: float = 10.0        # how far the nominal joint zeros may be off (search range)
    max_base_mm: float = 100.0        # how far the nominal base may be off (search range)
    finished_fraction: float = 0.7    # with no images list: every usable photo sees at least
                                      # this share of the persistent dots, so each shows the
                                      # finished sheet (else a series; vision_cal.identify.infer)


@dataclass(frozen=True)
class SelectionConfig:
    """Which effects are added to the base model (``vision_cal.estimate.select``) and which
    marks are left out of a fit (``vision_cal.model.lsq``)."""

    alpha: float = 0.01               # family-wise F-test level, split over the candidates
                                      # (Bonferroni: clean data claims nothing)
    k_folds: int = 5                  # cross-validation folds when < 3 validation marks
    max_effects: int = 4              # effects added at most
    outlier_sigma: float = 5.0        # a mark this many robust sigmas off is left out
    min_scan_dof: int = 20            # residual dof below which no structure is looked for
                                      # (unexplained: periodograms need that many)
    min_sheet_marks: int = 12         # marks below which the sheet map is not tested
    min_sheet_affine: float = 5e-4    # a sheet_affine (paper scale along x or y, or shear)
                                      # smaller than this is not claimed, however
                                      # significant: the sheet's 100 mm scale bars read with
                                      # a ruler to 0.05 mm cannot confirm less (issue 28:
                                      # 0.012 % claimed on a robot with none)


@dataclass(frozen=True)
class FitConfig:
    """Identifiability of a least-squares fit (``vision_cal.model.lsq``)."""

    condition_number_limit: float = 1e8   # singular values of the column-scaled Jacobian
                                          # below the largest / this count as zero: a rank
                                          # below the parameters is a fit that cannot tell
                                          # them apart (double precision leaves ~1e-8 of a
                                          # parameter after a 1e8 amplification)


@dataclass(frozen=True)
class PhotoOffsetConfig:
    """Photos whose marks are shifted together (``vision_cal.estimate.photos``)."""

    gate_mm: float = 0.5              # a photo's dot belongs to the mark estimate within this
                                      # distance (marks are >= 3 mm apart, offsets ~0.05 mm)
    alpha: float = 0.001              # a photo is flagged when the chi-square p of its mean
                                      # offset is below this (a dozen photos: rarely by chance)


@dataclass(frozen=True)
class SheetFitConfig:
    """The sheet-fit gate: the marker-corner RMS a photo of the declared sheet may leave,
    ``print_scale * marker side + lens_px * mm per pixel`` (``vision_cal.measure.sheetfit``)."""

    print_scale: float = 0.01   # a printer scales the page up to ~1 %; a marker printed off
                                # its declared size by that leaves up to this over its side
    lens_px: float = 2.0        # a lens nobody declared, before (or without) its estimate.
                                # Set from the false rejections on hand-held phone series
                                # (bench/phone.py --gate: JPEG, focus breathing 1.5 %, k1
                                # -0.04..-0.08 undeclared, files stored turned with EXIF 6),
                                # measured without a lens. Seeds 0-4 (60 photos): 1 px refuses
                                # 6.7 %, 1.5 and 2 px none; seeds 10-19 (6 photos each): up to
                                # 1.48 px beyond the print term, so 1.5 px would refuse about
                                # one photo in a hundred; 2 px keeps a third of margin. Seeds
                                # 100-109 (not tuned on, 120 photos): 1 px 14.2 %, 2 px 0 %.
                                # The gate keeps its power: markers declared 27 mm for 30 leave
                                # 2.1 mm at 0.65 mm/px against 1.6 allowed. With the series'
                                # lens the corners leave <= 0.1 px.
    # beyond that allowance the misfit is split (issue 28): what a lens would explain (a
    # homography after k1 k2 p1 p2 about the image centre), then a smooth field over the
    # sheet (a print's feed wave and bow, a paper not flat: a polynomial in the sheet's x y
    # of degree 3 with 16 markers to 7 with 60, no more terms than a sixth of the corners), and
    # what is left. A photo whose leftover is within the allowance above is measured.
    smooth_max_mm: float = 2.0  # largest RMS the smooth field may take: a printer's feed
                                # wave and bow leave 0.17 mm RMS (0.30 max, issue 28), a
                                # paper 3 mm high seen 30 deg off the normal 1.7 mm
    smooth_min_markers: int = 16  # the field (a cubic at least: 20 terms) only from this
                                # many markers (64 corners, 128 equations)
    lens_min_markers: int = 6   # the lens terms (12 with the homography) from this many
    wrong_place_side: float = 0.25  # a leftover beyond this fraction of the marker side
                                # is no print, paper or lens: markers elsewhere than
                                # declared (other ids or layout). Measured on the real
                                # ChArUco photos (fixtures/real_charuco_opencv): the
                                # leftover is 0.3-0.5 px there; shuffled ids leave ~1 side


@dataclass(frozen=True)
class GridConfig:
    """The printed grid read around each dot (``vision_cal.measure.grid``)."""

    window_step_mm: float = 0.15      # window sampling (a pixel is 0.2-0.4 mm on the sheet)
    window_half_mm: float = 9.0       # window half-size: +-9 mm holds 18 lines at many pixel
                                      # phases (the photo's patches are cut this wide)
    min_periods: float = 3.0          # the window must hold this many pitches of usable
                                      # profile per axis (fewer: the phase is not defined)
    dark_fraction: float = 0.7        # samples below this fraction of the paper level are
                                      # not grid (pen, marker, text)
    min_contrast: float = 6.0         # |Fourier amplitude| / its noise below this: the lines
                                      # are not seen (the phase's std would exceed pitch / 38)
    print_length_min_mm: float = 60.0  # the printer's displacement between the markers
    print_length_max_mm: float = 400.0  # (measure/grid_print): its smoothness along x and
                                      # along y, five lengths from min to max (a feed wave, a
                                      # bow: 100 mm and more), the likeliest taken
    print_amplitude_max: float = 6.0  # and its std far from every marker: seven from half to
                                      # this many times the unmeasured print's
                                      # (uncertainty.unmeasured_print_mm / sqrt 2 per axis)


@dataclass(frozen=True)
class SheetHeightConfig:
    """The paper's height from parallax and its map (``vision_cal.measure.height``; the
    share of a photo's error common to its other photos is ``association.common_fraction``)."""

    offset_floor_mm: float = 0.008    # per-photo floor on a grid offset's std: what the Fourier
                                      # phase cannot resolve of the printed lines (aliasing of
                                      # their sharp profile), seen as 5-8 um on rendered photos
    alpha: float = 1e-3               # level of the flat-sheet chi-square test and of the
                                      # evidence that the offsets are heights (lens, mapping)
    min_claim_mm: float = 0.05        # a height map whose marks all stay below this is flat
                                      # (well under the 0.1 mm a raised paper makes matter)
    map_step_mm: float = 20.0         # the height map's grid step (the GP's length >= 30 mm)
    same_place_fraction: float = 0.02  # camera centres closer than this fraction of their
                                      # height are one place (a fixed camera)
    min_parallax_baseline: float = 0.05  # spread of the parallax directions v (mm per mm of
                                      # height) below which height and position are not
                                      # separable between places (the same view every time)


@dataclass(frozen=True)
class PlanMatchConfig:
    """Photos that do not belong to the session (``vision_cal.identify.plan_match``)."""

    max_dots_per_mark: float = 2.0    # a photo showing more than this many dots per mark it
                                      # should show (plus ``spare_dots``) is crowded: in most
                                      # photos, another, finished sheet
    spare_dots: int = 3               # dots allowed beyond that (blemishes, a pilot's marks)
    min_matched_fraction: float = 0.5  # fewer planned marks matched to a dot: the dots are
                                      # not where the plan and the robot model put them
    min_marks_judged: int = 6         # marks the photos should show before that is judged
                                      # (a reversed series of three photos is a wrong order)


@dataclass(frozen=True)
class PhotoAgreementConfig:
    """A photo whose dots all sit away from where the others see them
    (``vision_cal.measure.photo_agreement``)."""

    min_photos: int = 3               # usable photos needed, so that "the others" agree
    min_dots: int = 3                 # dots a photo shares with the others to be judged
    search_mm: float = 3.0            # a dot's nearest dot of another photo within this is
                                      # the same dot (marks are >= 3 mm apart)
    max_offset_mm: float = 0.25       # median displacement beyond this: the photo moved as a
                                      # whole (far beyond a mapping's error of hundredths of a
                                      # mm, far below the spacing of marks)
    spread_factor: float = 3.0        # ... and beyond this many times the displacements'
                                      # own robust scatter (not dots that happen to be near)


@dataclass(frozen=True)
class GridDeclarationConfig:
    """A printed grid that is not where ``sheet.grid`` declares it
    (``vision_cal.measure.grid_declaration``)."""

    min_dots: int = 3                 # dots with a grid offset needed to judge
    min_agreement: float = 0.9        # mean resultant length of the lines' phase over the dots
                                      # above this: one constant offset everywhere
    min_offset_mm: float = 0.05       # its mean beyond this (a raised paper moves the lines
                                      # by parallax, differently at each place) ...
    min_offset_sigmas: float = 5.0    # ... and beyond this many standard errors (of the
                                      # marks and camera places, not of the photos: a
                                      # series repeats each mark from one place)
    alpha: float = 1e-3               # a height per mark along its parallax direction that
                                      # explains the offsets better than the constant alone
                                      # (F test at this level) makes them a raised paper,
                                      # not a wrong declaration (issue 28: a bumped sheet
                                      # under a fixed camera tilted 15 deg)
    same_mark_mm: float = 1.0         # dots of different photos this close are one mark


@dataclass(frozen=True)
class SmoothResidualConfig:
    """The test for a spatially smooth residual over the sheet (``vision_cal.estimate.sheet``)."""

    alpha: float = 1e-3               # permutation-test level: the smoothed residual agrees
                                      # with the residual more than shuffled marks do
    length_mm: float = 60.0           # Gaussian smoothing length (a fold or curl of the paper
                                      # spans several cm; the marks are ~20-40 mm apart)
    map_step_mm: float = 40.0         # the reported map's grid step
    n_permutations: int = 1999        # permutations of the test (p resolved to 5e-4)


@dataclass(frozen=True)
class DiscoveryConfig:
    """The scans for effects no candidate names (``vision_cal.estimate.discover``)."""

    max_terms: int = 4                # joint-polynomial terms discovery adds at most (each
                                      # costs a parameter; 4 keep the pilot's dof for the test)
    scan_level: float = 0.5           # scans and discovery run at this share of the
                                      # selection's alpha (the rest is the named candidates')
    heldout_tie: float = 1.25         # held-out RMS ratio within which fewer parameters win
                                      # (the held-out RMS of ~30 marks is known to ~13 %, 2 std)


@dataclass(frozen=True)
class Joint4Config:
    """The joint-4 stage: the tool's offset from the joint-4 axis
    (``vision_cal.estimate.joint4``)."""

    accept_sigma: float = 4.0         # an offset term is kept only when its estimate exceeds
                                      # this many reported std (two terms tested: by chance
                                      # below 1e-4)


@dataclass(frozen=True)
class VerdictConfig:
    """The noise-floor gate and the status rule (``vision_cal.estimate.verdict``)."""

    default_repeatability_mm: float = 0.01  # the robot's repeatability (mm, per axis, one std)
                                      # when neither repeated marks nor the robot block give
                                      # it: a SCARA catalogue's +-0.01 mm read as one std
                                      # (conservative: catalogues quote more)
    floor_alpha: float = 1e-3         # chi-square level of the gate (and of the largest error)
    floor_ratio_tol: float = 1.25     # residual / floor below this passes at any p: within how
                                      # well a measurer knows its own noise (its sigma to ~25 %)
    not_reliable_ratio: float = 2.0   # beyond the floor by this much: do not plan with the model
    heldout_warn_ratio: float = 3.0   # held-out RMS above this many times the fitted RMS: check
    min_spare_dof: int = 8            # 2 N - P below this: too few marks to test any effect
    min_repeat_pairs: int = 4         # pairs of marks drawn at the same command needed to
                                      # measure repeatability (fewer: the robot block's figure)
    # a declared arm-camera lens against the views' own (camera/arm.check_declared_lens):
    # contradicted beyond lens_sigma of the views' std *and* a difference that matters
    lens_sigma: float = 4.0           # std of the views' estimate
    lens_min_f_rel: float = 0.005     # focal length: 0.5 % (1 mm of height at 200 mm)
    lens_min_px: float = 0.1          # distortion at the farthest corner seen: 0.1 px (the
                                      # sub-pixel corners' own scale)

    print_check_mm: float = 0.01      # the print's limit on the marks (2-D RMS) seen from one
                                      # camera place beyond this: check (a survey measures it)


@dataclass(frozen=True)
class VerifyConfig:
    """The check of a calibration on a new sheet (``vision-cal verify``,
    ``vision_cal.estimate.verify``): when a base parameter moved and when the marks still
    hold what the calibration promised. Judged with the calibrated file's own record (the
    defaults for a file written before it)."""

    moved_sigma: float = 4.0          # a parameter moved when its change exceeds this many of
                                      # its std (the one covariance policy, scaled by the
                                      # check's residual variance)
    tolerance_factor: float = 2.0     # still good: the marks' RMS (the sheet's placement taken
                                      # out) within this many times the promised error (its
                                      # held-out RMS, or the check's own noise when larger)


@dataclass(frozen=True)
class HandeyeConfig:
    """The hand-eye from pose pairs (``vision_cal.camera.pose_pairs``, issue 32)."""

    min_pairs: int = 4                # 11 parameters, 6 rows a pair: four leave 13 dof
    min_yaw_spread_deg: float = 5.0   # the flange must turn between pairs by this much, else
                                      # the camera's x, y on it are not seen at all
    outlier_alpha: float = 0.001      # a pair is left out when its deleted translation or
                                      # rotation residual (3-D, per-axis scatter) is beyond this
                                      # level over all the pairs (alpha / N each); 0.001:
                                      # with the scatter estimated from 20 pairs, clean
                                      # simulated pairs lose one pair in ~30 sets
                                      # (bench/handeye_pairs.py)
    max_outlier_fraction: float = 0.3  # never leave out more than this share of the pairs
    unidentified_std_mm: float = 5.0  # a translation whose std is above this (mm) ...
    unidentified_std_deg: float = 2.0  # ... or a rotation above this (deg): not identifiable
    # issue 40-41: the pairs checked against each other (camera/pairs_checks.py)
    max_pairs: int = 100_000          # more pairs are refused (the fit is linear in them:
                                      # 10,000 take seconds, bench/handeye_pairs.py --speed)
    progress_pairs: int = 2_000       # from this many pairs on, a progress line a stage
    repeat_mm: float = 1e-3           # flange poses within this (mm) ...
    repeat_deg: float = 1e-3          # ... and this (deg) are one pose, counted once
    consensus_trials: int = 220       # random triples tried (every one of fewer pairs): with
                                      # 60 % of the pairs bad, a clean one unfound 1 in 10^6
    consensus_share: float = 0.4      # a triple is scored by the pairs' spread at this
                                      # quantile: up to 60 % of the pairs may be wrong
    consensus_cut: float = 5.0        # pairs beyond this many times that spread are left out
                                      # before the weighted fit tests the rest one by one
    convention_ratio: float = 4.0     # another reading of the pairs (mount, an inverse, a
                                      # transpose, degrees) agreeing this many times better
                                      # than the one given is named as the likely cause
    convention_sample: int = 500      # pairs (spread over the file) the readings are tried on
    unit_ratio: float = 1.5           # the target's translations this many times the flange's
                                      # motion (or less): two units
    scale_min_rel: float = 0.01       # ... off 1 by more than this share and scale_sigma
    scale_sigma: float = 5.0          # std: the board's size declared to its detector off?
    min_reach_mm: float = 100.0       # a flange never this far from the robot's axis: not a
                                      # SCARA in mm (Yamaha's YK120 reaches 120 mm)
    max_mount_mm: float = 2_000.0     # a camera or a target further from the flange: no mount
    max_robot_mm: float = 10_000.0    # ... or from the robot's base: no workcell


@dataclass(frozen=True)
class HandeyePhotosConfig:
    """The hand-eye from photos of a board and the robot's poses, any arm
    (``vision_cal.camera.handeye``, issue 40)."""

    min_photos: int = 4               # 12 unknowns (and the lens): three photos leave two
                                      # motions, the least that fixes them; one more to judge
    min_points: int = 6               # a photo with fewer board points cannot give a pose
    min_rotation_spread_deg: float = 10.0  # the flange must turn this much between photos
                                      # (else the camera's place on it is not seen)
    min_axis_spread_deg: float = 2.0  # ... about more than one axis: all turns about one
                                      # axis (a SCARA) leave the translation along it unseen
    max_rotation_disagreement_deg: float = 3.0  # the closed form's rotations disagreeing by
                                      # more (RMS) than this: the poses' convention is not
                                      # the stated one (real session: 0.18 deg, 1.3 deg from
                                      # 4 photos through a lens without distortion; a wrong
                                      # convention or a shift by one photo: tens of deg)
    max_scale_error: float = 0.05     # the robot's motion and the board's as seen differing
                                      # in scale by more than this fraction: units, the
                                      # board's size or the lens (real session: 0.8 %)
    max_scale_error_estimated: float = 0.3  # the same when the lens is estimated: its start
                                      # from a few views is off by several % (4 real photos:
                                      # 8 %), which the least squares corrects
    photo_fit_factor: float = 4.0     # a photo whose own pose fit (PnP) leaves more than
                                      # this times the median photo's residual ...
    photo_fit_px: float = 2.0         # ... and more than this (px RMS) does not show this
                                      # board (or the lens is far off in that part)
    outlier_alpha: float = 0.001      # a photo predicted by the others beyond what is stated
                                      # for it at this level (alpha / n each) is left out
    outlier_ratio: float = 4.0        # ... and only when also this many times farther off
                                      # (RMS) than stated: a real arm's pose errors have
                                      # heavier tails than a normal law (real session: up
                                      # to 2x), a wrong pose or another board is off 10-30x
    max_outlier_fraction: float = 0.3  # never leave out more than this share of the photos
    heldout_alpha: float = 0.01       # held-out photos predicted worse than stated at this
                                      # level: the stds are raised to what they show, check
    dominant_pose_ratio: float = 2.0  # the robot's pose error is named as the limit when the
                                      # pixels it moves a photo by exceed the corners' noise
                                      # by this factor
    lens_models: str = "k1; k1 k2; k1 k2 p1 p2"  # the distortion models an undeclared lens
                                      # is tried with (with fx fy cx cy), ";" between: the
                                      # one whose held-out photos are predicted best is kept
                                      # (real session, 8 photos: 1.71, 1.67, 1.94 px)
    declared_lens_ratio: float = 1.5  # a declared lens whose held-out error is this many times
                                      # an estimated lens's is named ...
    declared_lens_std: float = 4.0    # ... or one whose fx, fy, cx or cy lies more than this
                                      # many stds from the estimate (4 terms tested: a false
                                      # alarm in 1 of 4000 when right)
    kinematic_length_rad: float = 1.0  # the robot's kinematic error is shared by two photos
                                      # as exp(-d^2 / 2 L^2) of their distance d over the
                                      # joints (rad; without joints: flange position over
                                      # the arm's reach and rotation): a model length or
                                      # angle off turns with its joint, so one radian apart
                                      # shares about cos 1 of it (0: no kinematic term, the
                                      # pose error independent from photo to photo)


@dataclass(frozen=True)
class AsPrintedConfig:
    """The sheet as printed, from several views (``vision_cal.measure.asprinted``, #28)."""

    min_places: int = 3               # distinct camera places needed to release the layout
                                      # (two leave the print and the lens nearly confounded)
    place_move: float = 0.05          # camera centres further apart than this fraction of
                                      # their distance to the sheet are two places ...
    place_turn_deg: float = 3.0       # ... or views turned more than this
    min_views: int = 2                # a corner is released when this many photos see it
    noise_px: float = 0.2             # the corners' noise assumed by the prior's weight
    prior_mm: float = 1.0             # the prior on each corner's deviation: a printer is
                                      # within tenths of a mm; holds what the views do not fix
    min_deviation_ratio: float = 3.0  # the layout is measured as printed only when its
                                      # deviation (RMS) exceeds this many times what the
                                      # views leave unresolved: else the declared one is kept
    focal_scatter: float = 0.1        # an undeclared lens: each photo's focal length may
                                      # differ from the others' by about this fraction (a
                                      # phone refocuses between photos; the prior's width)
    huber_px: float = 1.0             # residuals beyond this count linearly (a corner on an
                                      # arm's edge must not bend the layout)
    single_view_factor: float = 1.0   # one place: the print's deviation the marker corners
                                      # show beyond the homography, times this, is the marks'
                                      # systematic uncertainty (2-D): the pose takes part of
                                      # the print, the robot fit part of what is left (a 0.17
                                      # mm print: 0.15 mm seen, marks 0.08 mm off)
    lens_free_interior_factor: float = 2.0   # an undeclared lens solved with the print: what
                                      # it leaves on the marks between the markers
                                      # (``interior_mm``, from the solve's own Jacobian) times
                                      # this is carried (limit, sigma, field): the radial terms
                                      # trade with the paper's unmeasured shape between the
                                      # markers and the edges' bias, which the covariance
                                      # does not hold (issue 37, world2 seeds 101-105: the
                                      # marks' field-shaped error 1.2-2.4x, median 1.95x it)
    release_heights: bool = True      # each released corner's height off the paper's plane
                                      # is solved too: paper that is not flat shows parallax
                                      # between places, which in-plane shifts alone take
                                      # for print (a bumped sheet, 0.3-1 mm, from four
                                      # places: 0.11-0.26 mm of false print)
    height_prior_mm: float = 2.0      # the prior on each corner's height (paper off flat by
                                      # a few mm at most; holds the heights' gauge)
    survey_good_mm: float = 0.02      # a survey whose corners are known to this (2-D RMS of
                                      # their std) says "good"; else what limits it
    max_evaluations: int = 100        # each bundle adjustment stops after this many
                                      # evaluations; one that stops there has not converged
                                      # and is a failed solve, never a result (issue 37: a
                                      # DSLR survey stopped there and its field was applied)
    replication_max_chi2_dof: float = 3.0  # the print field is applied only when the two
                                      # halves' fields (camera places split in two) agree:
                                      # chi2/dof of their difference against the covariance
                                      # each half states at most this, i.e. they scatter at
                                      # most 1.7 times the std stated (chance alone exceeds
                                      # 1.45 once in a thousand at 100 dof); within it the
                                      # field is the paper's and its std is scaled by
                                      # sqrt(chi2/dof) (print.stated_scale). Two cameras'
                                      # fields of one print that did not describe one print:
                                      # 4.8 (issue 37); real halves of one camera 0.4-0.7;
                                      # the rendered print-off world 1.55-1.89 (a 0.17 mm
                                      # field, halves 0.04 mm apart: applied, marks 0.005-
                                      # 0.008 mm)
    replication_min_corners: int = 8  # corners both halves released below this: the halves
                                      # cannot be compared (8 x 2 values less the gauge's 4)
    field_alpha: float = 0.001        # a print field is significant when its chi-square
                                      # against its own covariance has a p-value below this
                                      # (a layout on its declared one passes this once in a
                                      # thousand); a layout from the calibration's own photos
                                      # must also exceed min_deviation_ratio (a bumped
                                      # sheet's false print replicates)
    gauge_tolerance_mm: float = 0.001  # a survey read back: its layout's best-fitting
                                      # similarity to the declared one moves no released
                                      # corner more than this (the solve fixes it to the
                                      # identity, 1e-12 mm; a file scaled by 1.01 after it
                                      # was written moves them 1-2 mm: refused)
    max_deviation_mm: float = 5.0     # a survey read back: no corner further than this off
                                      # its layout (printers are tenths off; the prior,
                                      # prior_mm, holds 1 mm at one sigma)


@dataclass(frozen=True)
class UncertaintyConfig:
    """What a stated std holds beyond the fit's covariance (issue 37): the repeatability the
    repeated marks measure, the print when it is not measured, the paper's scale, the
    replication of the fit by two halves of the marks (:mod:`vision_cal.estimate.verdict`,
    :mod:`vision_cal.estimate.replicate`, :mod:`vision_cal.plan.uncertainty`)."""

    repeat_resolve_sigmas: float = 2.0  # the pairs' unbiased estimate of r^2 must stand this
                                      # many of its own std above 0 to be the repeatability;
                                      # else they do not resolve it from the measurement
                                      # noise and the prior is used, capped by the pairs'
                                      # upper bound (r^2 + this many std): never 0
    unmeasured_print_mm: float = 0.07  # the print not measured (no survey, photos from fewer
                                      # than as_printed.min_places places: a fixed camera):
                                      # its deviation on every mark (2-D RMS, shared, not
                                      # averaged), at least: a printer puts ink 0.1-0.3 mm off
                                      # its layout; the photos' mapping and the robot fit take
                                      # the smooth part, a 0.17 mm RMS print left the marks
                                      # 0.08 mm and the targets 0.07 mm RMS off (#28)
    paper_scale_std: float = 0.002    # the paper's overall scale (one std, relative) when the
                                      # printed bars were not measured: paper grows and shrinks
                                      # 0.1-0.3 % with humidity and a printer's scale is within
                                      # about 0.1 %; marks on the paper cannot tell it from the
                                      # link lengths
    bar_reading_mm: float = 0.05      # one std of a printed 100 mm bar measured with a caliper
                                      # (the caliper reads 0.02 mm; setting its jaws on the
                                      # printed ends by eye, about 0.05 mm)
    min_half_dof: int = 4             # a half of the marks fitted alone keeps at least this
                                      # many degrees of freedom (2 n - P), else the fit is not
                                      # replicated


@dataclass(frozen=True)
class EstimatorConfig:
    """All the knobs, by part; the keys of calibration.json ``config``."""

    markers: MarkerConfig = field(default_factory=MarkerConfig)
    dots: DotConfig = field(default_factory=DotConfig)
    association: AssociationConfig = field(default_factory=AssociationConfig)
    selection: SelectionConfig = field(default_factory=SelectionConfig)
    fit: FitConfig = field(default_factory=FitConfig)
    per_photo_offsets: PhotoOffsetConfig = field(default_factory=PhotoOffsetConfig)
    sheet_fit: SheetFitConfig = field(default_factory=SheetFitConfig)
    grid: GridConfig = field(default_factory=GridConfig)
    sheet_height: SheetHeightConfig = field(default_factory=SheetHeightConfig)
    plan_match: PlanMatchConfig = field(default_factory=PlanMatchConfig)
    photo_agreement: PhotoAgreementConfig = field(default_factory=PhotoAgreementConfig)
    grid_declaration: GridDeclarationConfig = field(default_factory=GridDeclarationConfig)
    smooth_residual: SmoothResidualConfig = field(default_factory=SmoothResidualConfig)
    discovery: DiscoveryConfig = field(default_factory=DiscoveryConfig)
    joint4: Joint4Config = field(default_factory=Joint4Config)
    verdict: VerdictConfig = field(default_factory=VerdictConfig)
    verify: VerifyConfig = field(default_factory=VerifyConfig)
    handeye: HandeyeConfig = field(default_factory=HandeyeConfig)
    handeye_photos: HandeyePhotosConfig = field(default_factory=HandeyePhotosConfig)
    as_printed: AsPrintedConfig = field(default_factory=AsPrintedConfig)
    uncertainty: UncertaintyConfig = field(default_factory=UncertaintyConfig)

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict | None) -> "EstimatorConfig":
        """The recorded config; parts or fields an older file lacks take the defaults."""
        d = d or {}
        parts = {}
        for f in fields(cls):
            part = f.default_factory
            known = {g.name for g in fields(part)}
            parts[f.name] = part(**{k: v for k, v in (d.get(f.name) or {}).items()
                                    if k in known})
        return cls(**parts)


#: what every function uses when it is given no config
DEFAULT = EstimatorConfig()
