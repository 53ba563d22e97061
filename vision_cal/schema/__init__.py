"""JSON Schemas of the files vision-cal reads and writes (docs/format.md), shipped with
the package: ``load_schema("session")`` and :func:`validate` for tests and other tools.

The schemas encode ``vision-cal/1`` (the format as docs/format.md gives
it): required fields and their types, units in the names; every object
accepts added fields, as the format allows."""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

NAMES = ("session", "sheet", "robot", "calibration", "poses", "robot_pose")


@lru_cache(maxsize=None)
def load_schema(name: str) -> dict:
    """The schema ``vision_cal/schema/<name>.schema.json`` (with shared ``$defs``)."""
    if name not in NAMES:
        raise KeyError(f"no schema {name!r} (expected one of {', '.join(NAMES)})")
    text = resources.files(__package__).joinpath(f"{name}.schema.json").read_text("utf-8")
    return json.loads(text)


def validate(doc, name: str) -> None:
    """Raise ``jsonschema.ValidationError`` if ``doc`` does not follow schema ``name``."""
    # jsonschema: loaded here, when a schema is checked
    import jsonschema

    jsonschema.validate(doc, load_schema(name), cls=jsonschema.Draft202012Validator)
