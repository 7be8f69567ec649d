"""YAML with line numbers, and typed access to the keys of one mapping, for errors as ``file:line: what``.

The building blocks of scenario parsing: :class:`Ctx` knows the file, :class:`Fields` reads the
keys of one mapping with their type, range and unit checked, and reports unknown keys with the
allowed ones.
"""

from __future__ import annotations

import math
from typing import Any

import yaml


class ScenarioError(ValueError):
    """A scenario file is not valid; the message starts with ``file:line:``."""


# ----- YAML with line numbers ---------------------------------------------------------------
class LineMap(dict[Any, Any]):
    """A YAML mapping that knows its line and the line of each key (1-based)."""

    line: int = 0
    key_lines: dict[Any, int]


class LineList(list[Any]):
    """A YAML sequence that knows its line and the line of each item (1-based)."""

    line: int = 0
    item_lines: list[int]


class _Loader(yaml.SafeLoader):
    pass


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LineMap:
    loader.flatten_mapping(node)
    result = LineMap()
    result.line = node.start_mark.line + 1
    result.key_lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in result:
            raise yaml.MarkedYAMLError(problem=f"duplicate key {key!r}", problem_mark=key_node.start_mark)
        result[key] = loader.construct_object(value_node, deep=True)
        result.key_lines[key] = key_node.start_mark.line + 1
    return result


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> LineList:
    result = LineList(loader.construct_object(child, deep=True) for child in node.value)
    result.line = node.start_mark.line + 1
    result.item_lines = [child.start_mark.line + 1 for child in node.value]
    return result


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


class Ctx:
    """Where we are in the file, to prefix errors with ``file:line:``."""

    def __init__(self, file: str) -> None:
        self.file = file

    def error(self, line: int, message: str) -> ScenarioError:
        return ScenarioError(f"{self.file}:{line}: {message}")

    def load_yaml(self, text: str) -> Any:
        """Parse ``text`` into LineMap / LineList / scalars; YAML errors become ScenarioErrors."""
        try:
            return yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader derives from yaml.SafeLoader
        except yaml.MarkedYAMLError as error:
            mark = error.problem_mark or error.context_mark
            line = mark.line + 1 if mark is not None else 1
            raise self.error(line, f"not valid YAML: {error.problem or error}") from None
        except yaml.YAMLError as error:
            raise self.error(1, f"not valid YAML: {error}") from None


def line_of(obj: Any, default: int) -> int:
    """The line of a YAML mapping or list, or ``default`` for scalars."""
    return int(getattr(obj, "line", default) or default)


def key_line(mapping: Any, key: Any) -> int:
    """The line of ``key`` in a YAML mapping (the mapping's own line when unknown)."""
    lines = getattr(mapping, "key_lines", {})
    return int(lines.get(key, line_of(mapping, 0)))


def item_line(items: Any, index: int) -> int:
    """The line of item ``index`` of a YAML list."""
    lines = getattr(items, "item_lines", None)
    return lines[index] if lines else line_of(items, 1)


def kind_of(value: Any) -> str:
    """What a YAML value is, for error messages."""
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return repr(value)


Vector3 = tuple[float, float, float]


class Fields:
    """Typed access to the keys of one mapping; reports missing and unknown keys and wrong types.

    Read every key through one of the methods, then call :meth:`done`: a key that was not read is
    reported as unknown, with the keys that were.
    """

    def __init__(self, ctx: Ctx, mapping: Any, what: str, line: int) -> None:
        self.ctx = ctx
        self.what = what
        self.line = line_of(mapping, line)
        if not isinstance(mapping, dict):
            raise ctx.error(self.line, f"{what} must be a mapping (key: value), got {kind_of(mapping)}")
        self.mapping: dict[Any, Any] = mapping
        self.used: set[str] = set()

    def error(self, line: int, message: str) -> ScenarioError:
        """An error about this mapping: ``file:line: <what>: message``."""
        return self.ctx.error(line, f"{self.what}: {message}")

    def at(self, key: str) -> int:
        return key_line(self.mapping, key)

    def has(self, key: str) -> bool:
        return key in self.mapping

    def raw(self, key: str, default: Any = None) -> Any:
        self.used.add(key)
        return self.mapping.get(key, default)

    def _missing(self, key: str) -> ScenarioError:
        return self.error(self.line, f"missing required key {key!r}")

    # numbers
    def optional_number(self, key: str, low: float | None = None, high: float | None = None, unit: str = "") -> float | None:
        """A finite number within [low, high], or None when the key is absent."""
        self.used.add(key)
        if key not in self.mapping:
            return None
        value = self.mapping[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
            raise self.error(self.at(key), f"{key} must be a number{unit}, got {value!r}")
        value = float(value)
        if low is not None and value < low:
            raise self.error(self.at(key), f"{key} must be >= {low}{unit}, got {value}")
        if high is not None and value > high:
            raise self.error(self.at(key), f"{key} must be <= {high}{unit}, got {value}")
        return value

    def number(self, key: str, default: float, low: float | None = None, high: float | None = None, unit: str = "") -> float:
        value = self.optional_number(key, low, high, unit)
        return float(default) if value is None else value

    def required_number(self, key: str, low: float | None = None, high: float | None = None, unit: str = "") -> float:
        value = self.optional_number(key, low, high, unit)
        if value is None:
            raise self._missing(key)
        return value

    def integer(self, key: str, default: int) -> int:
        self.used.add(key)
        value = self.mapping.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(self.at(key), f"{key} must be an integer, got {value!r}")
        return value

    # strings
    def optional_string(self, key: str, choices: tuple[str, ...] | None = None) -> str | None:
        """A string (one of ``choices`` when given), or None when the key is absent."""
        self.used.add(key)
        if key not in self.mapping:
            return None
        value = self.mapping[key]
        if not isinstance(value, str):
            raise self.error(self.at(key), f"{key} must be a string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(self.at(key), f"{key} {value!r} is not one of: {', '.join(choices)}")
        return value

    def string(self, key: str, default: str, choices: tuple[str, ...] | None = None) -> str:
        value = self.optional_string(key, choices)
        return default if value is None else value

    def required_string(self, key: str, choices: tuple[str, ...] | None = None) -> str:
        value = self.optional_string(key, choices)
        if value is None:
            raise self._missing(key)
        return value

    def boolean(self, key: str, default: bool) -> bool:
        self.used.add(key)
        value = self.mapping.get(key, default)
        if not isinstance(value, bool):
            raise self.error(self.at(key), f"{key} must be true or false, got {value!r}")
        return value

    # vectors
    def optional_vector3(self, key: str, unit: str = "") -> Vector3 | None:
        """Three numbers, or None when the key is absent."""
        self.used.add(key)
        if key not in self.mapping:
            return None
        value = self.mapping[key]
        if (not isinstance(value, list) or len(value) != 3
                or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value)):
            raise self.error(self.at(key), f"{key} must be a list of 3 numbers{unit}, got {value!r}")
        return float(value[0]), float(value[1]), float(value[2])

    def required_vector3(self, key: str, unit: str = "") -> Vector3:
        value = self.optional_vector3(key, unit)
        if value is None:
            raise self._missing(key)
        return value

    def done(self) -> None:
        """Report the first key that no method read as unknown, with the allowed keys."""
        unknown = [key for key in self.mapping if key not in self.used]
        if unknown:
            key = unknown[0]
            known = ", ".join(sorted(self.used))
            raise self.error(self.at(key), f"unknown key {key!r}; allowed: {known}")
