"""How many photos each dot is refined in (issue 33).

A series adding marks photo by photo (the demo: photo k shows the first k marks) shows
every mark again in every later photo: refining each dot in each photo costs the product
of photos and marks. Past a few views a mark's centre hardly improves: what the views
share (the sheet mapping's and the print's error, ``association.common_fraction`` of a
view's variance) is not averaged away, and the covariance :func:`.associate.combine`
reports says so for any number of views. So the finish stage refines a dot in the first
``config.dots.views_per_dot`` photos (capture order) where it was measured reliably
(``unreliable`` empty); in later photos it is only *seen*: its blob's centroid through the
photo's mapping (``ImageResult.seen_xy_mm``), which is enough to group it with its
other views (a dot moves far less than ``association.group_tol_*``), to infer which marks a
photo shows and to find a photo moved as a whole, and which no mark's position,
covariance or height takes.

A camera that moves makes a mark's height observable by parallax between its places
(:mod:`vision_cal.measure.height`): a dot is therefore also refined in the first photo from
each camera place none of its views was taken from (places as the height stage tells them
apart, ``sheet_height.same_place_fraction``), so the count stays linear (views plus
places per dot).
"""

from __future__ import annotations

import numpy as np

from vision_cal.measure.height import place_of


class ViewCount:
    """Reliable refined views per place on the sheet, photo after photo.

    ``views``: how many a dot needs (0: every photo); ``tol_mm``: dots closer than this are
    the same dot (the association's grouping tolerance); ``place_fraction``: camera centres
    closer than this fraction of their height are one place."""

    def __init__(self, views: int, tol_mm: float, place_fraction: float = 0.02):
        self.views = int(views)
        self.tol_mm = float(tol_mm)
        self.place_fraction = float(place_fraction)
        self._xy = np.zeros((0, 2))
        self._n = np.zeros(0, int)
        self._places_of: list[set] = []
        self._centres: list[np.ndarray] = []

    def place(self, centre_mm) -> int:
        """The index of the camera place of a photo taken from ``centre_mm`` (3,) on the
        sheet frame; -1 for None (no lens: no parallax to keep)."""
        if centre_mm is None:
            return -1
        return place_of(self._centres, centre_mm, self.place_fraction)

    def _nearest(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(index of the nearest place, within tolerance) per point of ``xy`` (K, 2)."""
        if not len(self._xy) or not len(xy):
            return np.zeros(len(xy), int), np.zeros(len(xy), bool)
        d = np.linalg.norm(xy[:, None, :] - self._xy[None, :, :], axis=2)
        j = d.argmin(axis=1)
        return j, d[np.arange(len(xy)), j] <= self.tol_mm

    def wanted(self, xy_mm, place: int = -1) -> np.ndarray:
        """bool (K,): which dots at ``xy_mm`` (K, 2), seen from camera ``place``, still
        need refining: fewer than ``views`` reliable views, or none from this place."""
        xy = np.asarray(xy_mm, float).reshape(-1, 2)
        if self.views <= 0 or not len(self._xy):
            return np.ones(len(xy), bool)
        j, near = self._nearest(xy)
        known = np.array([place in self._places_of[i] for i in j], bool)
        return ~(near & (self._n[j] >= self.views) & known)

    def add(self, xy_mm, reliable, place: int = -1) -> None:
        """Count the refined dots of one photo from camera ``place`` at ``xy_mm`` (K, 2);
        ``reliable`` (K,) bool: only those count."""
        xy = np.asarray(xy_mm, float).reshape(-1, 2)
        for p, ok in zip(xy, reliable):
            if not ok:
                continue
            j, near = self._nearest(p[None])
            if near[0]:
                self._n[j[0]] += 1
                self._places_of[j[0]].add(place)
            else:
                self._xy = np.vstack([self._xy, p])
                self._n = np.append(self._n, 1)
                self._places_of.append({place})
