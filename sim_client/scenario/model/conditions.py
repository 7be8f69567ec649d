"""Comparisons, conditions and triggers: a measure compared with a value, and when to act on a running goal.

Expectations compare a measure with a value (:class:`Comparison`); a ``wait`` step waits until a
:class:`Condition` holds; a goal's ``cancel`` fires on a :class:`Trigger`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from sim_client.scenario.model.fields import Ctx, Fields
from sim_client.scenario.model.measures import Measure, parse_measure

COMPARISONS = ("near", "gte", "lte", "gt", "lt", "eq")


@dataclass(frozen=True)
class Comparison:
    """``op`` is one of near, gte, lte, gt, lt, eq. ``near`` uses ``tol`` or ``rel_tol``."""

    op: str
    value: Any
    tol: float | None = None
    rel_tol: float | None = None

    def allowed(self) -> float:
        if self.tol is not None:
            return self.tol
        return abs(float(self.value)) * float(self.rel_tol or 0.0)

    def holds(self, measured: Any) -> bool:
        if measured is None:
            return False
        if self.op == "eq":
            return bool(measured == self.value)
        try:
            measured = float(measured)
        except (TypeError, ValueError):
            return False
        if not math.isfinite(measured):
            return False
        if self.op == "near":
            return abs(measured - float(self.value)) <= self.allowed() + 1e-12
        return {"gte": measured >= self.value, "lte": measured <= self.value,
                "gt": measured > self.value, "lt": measured < self.value}[self.op]

    def describe(self) -> str:
        if self.op == "near":
            tol = f"±{self.tol:g}" if self.tol is not None else f"±{100 * float(self.rel_tol or 0):g}%"
            return f"{self.value:g} {tol}"
        symbol = {"gte": ">=", "lte": "<=", "gt": ">", "lt": "<", "eq": "=="}[self.op]
        return f"{symbol} {self.value}"


@dataclass(frozen=True)
class Condition:
    """A measure compared with a value, e.g. feedback distance_walked >= 1.0."""

    measure: Measure
    comparison: Comparison
    line: int

    def describe(self) -> str:
        return f"{self.measure.describe()} {self.comparison.describe()}"


@dataclass(frozen=True)
class Trigger:
    """When to act on a running goal: ``after`` sim seconds since it was sent, or ``when`` a condition holds."""

    after: float | None
    when: Condition | None
    line: int

    def describe(self) -> str:
        if self.when is not None:
            return f"when {self.when.describe()}"
        return f"after {self.after:g} s"


def parse_comparison(f: Fields) -> Comparison:
    """Exactly one of near (with tol or rel_tol), gte, lte, gt, lt, eq among the keys of ``f``."""
    ops = [op for op in COMPARISONS if f.has(op)]
    if len(ops) != 1:
        found = f"found {', '.join(ops)}" if ops else "found none"
        raise f.error(f.line, f"give exactly one comparison of {', '.join(COMPARISONS)} ({found})")
    op = ops[0]
    if op == "eq":
        return Comparison("eq", f.raw("eq"))
    value = f.required_number(op)
    if op == "near":
        tol = f.optional_number("tol", low=0.0)
        rel_tol = f.optional_number("rel_tol", low=0.0)
        if (tol is None) == (rel_tol is None):
            raise f.error(f.at("near"), "near needs exactly one of tol (absolute) or rel_tol (fraction, 0.05 = 5%)")
        return Comparison("near", value, tol, rel_tol)
    return Comparison(op, value)


def parse_condition(ctx: Ctx, raw: Any, line: int, what: str) -> Condition:
    f = Fields(ctx, raw, what, line)
    if not f.has("measure"):
        raise f.error(f.line, "missing required key 'measure'")
    measure = parse_measure(ctx, f.raw("measure"), f.at("measure"))
    comparison = parse_comparison(f)
    f.done()
    return Condition(measure, comparison, f.line)


def parse_trigger(ctx: Ctx, raw: Any, line: int, what: str) -> Trigger:
    f = Fields(ctx, raw, what, line)
    after = f.optional_number("after", low=0.0, unit=" [s of sim time]")
    when_raw = f.raw("when")
    when = parse_condition(ctx, when_raw, f.at("when"), f"{what}: when") if f.has("when") else None
    f.done()
    if (after is None) == (when is None):
        raise f.error(f.line, "give exactly one of 'after' (sim seconds after the goal was sent) or 'when' (a condition)")
    return Trigger(after, when, f.line)
