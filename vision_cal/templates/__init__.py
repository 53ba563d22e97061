"""Files vision-cal writes for the user to edit (``vision-cal robot-template``), shipped in
the package: ``robot.yaml`` (a commented robot file, docs/robot-file.md) and
``simulated_robot.yaml`` (a simulated robot for ``vision-cal simulate``)."""

from __future__ import annotations

from importlib import resources

TEMPLATES = {"robot": "robot.yaml", "simulated": "simulated_robot.yaml"}


def template_text(kind: str) -> str:
    """The text of the template ``kind`` (``robot`` or ``simulated``)."""
    return resources.files(__name__).joinpath(TEMPLATES[kind]).read_text(encoding="utf-8")
