"""Loco-manipulation: a biped fetches an object with both palms and places it on another table."""

from sim_bridge.fetch.goal import FetchGoal, FetchPlan, check_fetchable, check_place_on_a_table, plan_fetch
from sim_bridge.fetch.grip import GripConfig
from sim_bridge.fetch.skill import FetchSkill
from sim_bridge.fetch.stance import Stance, StanceConfig, plan_stance

__all__ = [
    "FetchGoal", "FetchPlan", "FetchSkill", "GripConfig", "Stance", "StanceConfig",
    "check_fetchable", "check_place_on_a_table", "plan_fetch", "plan_stance",
]
