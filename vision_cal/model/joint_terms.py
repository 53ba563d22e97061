"""The estimator's feature dictionary of ``joint_terms`` (docs/format.md, effect table).

A ``joint_terms`` effect says the joint turns ``sum(coef_k * f_k)`` degrees more than
commanded, each feature ``f_k`` a product of factors of the *commanded* angles (degrees)
and approach signs:

    q1, q2               the commanded angle (deg); ``q1^2``, ``q2^3``: its powers
    sin(h*q1), cos(q2)   harmonics of the angle (h = 1, 2, ...; argument in degrees)
    approach1/2          the approach sign (+1 / -1)

joined by ``*`` (``q1*q2``, ``q2*approach1``). ``t`` (drawing order) is *not* a joint
term: what depends on when a mark was drawn is ``drift``, never compensated.

:data:`DICTIONARY` is the list the discovery selects from (vision_cal.estimate.discover).
Inside the fit a feature is divided by :func:`unit` (100 deg per power of an angle), so
every column is of order one.
"""

from __future__ import annotations

import re

import numpy as np

from vision_cal.errors import VisionCalError

_FACTOR = re.compile(r"^(?:(?P<trig>sin|cos)\((?:(?P<h>\d+)\*)?q(?P<tj>[12])\)"
                     r"|q(?P<j>[12])(?:\^(?P<p>[1-4]))?|approach(?P<a>[12]))$")
ANGLE_UNIT_DEG = 100.0


def _factors(feature: str) -> list[str]:
    out, depth, cur = [], 0, ""
    for ch in feature.replace(" ", ""):
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        if ch == "*" and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    out.append(cur)
    return out


def check_feature(feature: str, where: str = "feature") -> str:
    """The feature, or a :class:`VisionCalError` naming ``where``."""
    if not isinstance(feature, str) or not feature:
        raise VisionCalError(f"expected a feature like 'q1*q2', got {feature!r}", field=where)
    for f in _factors(feature):
        if not _FACTOR.match(f):
            raise VisionCalError(f"unknown feature factor {f!r} in {feature!r} (expected q1, "
                                 "q2, q1^2, sin(h*q1), cos(h*q2), approach1, approach2 "
                                 "joined by *)", field=where)
    return feature


def unit(feature: str) -> float:
    """The scale the fit divides the feature by (100 deg per power of an angle)."""
    power = 0
    for f in _factors(feature):
        m = _FACTOR.match(f)
        if m and m.group("j"):
            power += int(m.group("p") or 1)
    return ANGLE_UNIT_DEG ** power


def evaluate(feature: str, q_deg, approach) -> np.ndarray:
    """Feature values (N,) for commanded angles ``q_deg`` (N, 2) deg and signs (N, 2)."""
    q = np.atleast_2d(np.asarray(q_deg, dtype=float))
    s = np.broadcast_to(np.asarray(approach, dtype=float), q.shape)
    out = np.ones(len(q))
    for f in _factors(check_feature(feature)):
        m = _FACTOR.match(f)
        if m.group("trig"):
            x = (int(m.group("h") or 1)) * np.radians(q[:, int(m.group("tj")) - 1])
            out = out * (np.sin(x) if m.group("trig") == "sin" else np.cos(x))
        elif m.group("j"):
            out = out * q[:, int(m.group("j")) - 1] ** int(m.group("p") or 1)
        else:
            out = out * np.where(s[:, int(m.group("a")) - 1] < 0, -1.0, 1.0)
    return out


def describe(joint: int, feature: str, coef_deg: float) -> str:
    """A term in words: "joint 2 turns 0.0012 deg more per degree of joint 1"."""
    fs = _factors(feature)
    if len(fs) == 1 and re.fullmatch(r"q[12]", fs[0]):
        return (f"joint {joint} turns {coef_deg:.3g} deg more per degree of joint "
                f"{fs[0][1]}")
    if len(fs) == 1 and re.fullmatch(r"q[12]\^\d", fs[0]):
        return (f"joint {joint} turns {coef_deg:.3g} deg more per (degree of joint "
                f"{fs[0][1]})^{fs[0][-1]}")
    return f"joint {joint} turns {coef_deg:.3g} deg x {feature} more"


#: the discovery's dictionary per joint error (both joints' angles: coupling included);
#: library effects (scale = q_j, harmonics 1-2 of q_j, approach_j) are in it as well so a
#: library effect is only claimed when it beats these with no more parameters
DICTIONARY = ("q1", "q2", "q1^2", "q2^2", "q1*q2", "q1^3", "q2^3",
              "sin(q1)", "cos(q1)", "sin(q2)", "cos(q2)",
              "sin(2*q1)", "cos(2*q1)", "sin(2*q2)", "cos(2*q2)",
              "sin(3*q1)", "cos(3*q1)", "sin(3*q2)", "cos(3*q2)",
              "approach1", "approach2")
