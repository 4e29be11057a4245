"""The command line's settings as text: `--set key=value` overrides, checked against each field's
type so that a typo is an error instead of a silently ignored setting, and `--seeds` lists.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from curious.config import MAX_SEED, OWN_OPTIONS, Config, ConfigError


def _coerce(name: str, annotation: str, text: str) -> Any:
    """Parse an override's text into the field's type (bool, int, float or str)."""
    kind = {"int": int, "float": float, "bool": bool, "str": str}[annotation]
    try:
        if kind is bool:
            lowered = text.strip().lower()
            if lowered in ("1", "true", "yes", "on"):
                return True
            if lowered in ("0", "false", "no", "off"):
                return False
            raise ValueError(text)
        if kind is int:
            return int(text.replace("_", ""))
        if kind is float:
            return float(text)
        return text
    except ValueError:
        wanted = {"int": "an integer", "float": "a number", "bool": "true or false"}[annotation]
        raise ConfigError(f"{name}={text!r}: expected {wanted}") from None


def parse_seeds(text: str) -> tuple[int, ...]:
    """`0-4` -> (0, 1, 2, 3, 4); `0,2,5` -> (0, 2, 5); ranges and single seeds mix, each seed
    once, in the order written. A `ConfigError` for anything else."""
    seeds: list[int] = []
    for part in text.split(","):
        first, dash, last = part.strip().partition("-")
        if not first.isdigit() or (dash and not last.isdigit()):
            raise ConfigError(f"seeds {text!r}: write them as 0-4 or 0,2,5")
        if dash and int(last) < int(first):
            raise ConfigError(f"seeds {text!r}: a range runs upwards ({last}-{first})")
        if int(last if dash else first) > MAX_SEED:
            raise ConfigError(f"seeds {text!r}: each must be from 0 to {MAX_SEED:,}")
        seeds += range(int(first), int(last) + 1) if dash else [int(first)]
    return tuple(dict.fromkeys(seeds))


def format_seeds(seeds: list[int] | tuple[int, ...]) -> str:
    """(0, 1, 2, 5) -> `0-2,5`: seeds as `--seeds` takes them (`parse_seeds`' inverse)."""
    parts: list[str] = []
    for seed in sorted(set(seeds)):
        if parts and parts[-1].rpartition("-")[2] == str(seed - 1):
            parts[-1] = f"{parts[-1].partition('-')[0]}-{seed}"
        else:
            parts.append(str(seed))
    return ",".join(parts)


def parse_overrides(items: list[str] | tuple[str, ...]) -> dict[str, Any]:
    """Turn `["key=value", ...]` into typed values; unknown keys and bad values are errors."""
    if isinstance(items, str):
        raise ConfigError(f"overrides are a list of 'key=value' strings, got one: [{items!r}]")
    types_by_name = {f.name: str(f.type) for f in fields(Config)}
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"override {item!r} is not of the form key=value")
        key, text = item.split("=", 1)
        key, text = key.strip().replace("-", "_"), text.strip()
        if key not in types_by_name:
            raise ConfigError(
                f"unknown config key {key!r}; known keys: {', '.join(sorted(types_by_name))}"
            )
        if key in OWN_OPTIONS:
            raise ConfigError(f"choose the {key} with {OWN_OPTIONS[key]}, not an override")
        out[key] = _coerce(key, types_by_name[key], text)
    return out
