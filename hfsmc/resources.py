"""Files shipped with hfsmc inside the wheel (schemas; templates come with the back ends)."""

from __future__ import annotations

import json
from functools import cache
from importlib.resources import files
from importlib.resources.abc import Traversable
from typing import Any


def schema_file(name: str) -> Traversable:
    return files("hfsmc.schemas").joinpath(name)


@cache
def json_schema() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(schema_file("hfsm.schema.json").read_text("utf-8"))
    return data
